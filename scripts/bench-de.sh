#!/usr/bin/env bash
# The Double-Eagle-size benchmark (not in CI): generates a plant of 127,000 objects and
# 82M triangles, builds it, and walks generated paths in-core and out-of-core (with and
# without prefetching) at a footprint of 1.2% (the paper's Double Eagle ratio), on the
# `ssd` and `hdd` disk models, with the `none` renderer at 10M triangles/s. Each step's
# wall time and peak RSS are printed (`/usr/bin/time`); the tables go to out/de/.
# Needs about 10 GiB of memory and 5 GiB of disk (the GLB, the scene and its staging copy).
# Usage: scripts/bench-de.sh [SEED] [PATH-KINDS] [DISKS] [FRAMES]
#   defaults: 2 flythrough,approach,orbit ssd,hdd 600
set -euo pipefail
cd "$(dirname "$0")/.."
seed="${1:-2}"
kinds="${2:-flythrough,approach,orbit}"
disks="${3:-ssd,hdd}"
frames="${4:-600}"
out="out/de/seed$seed"
mkdir -p "$out"
timed() { /usr/bin/time -f "$1: %e s, peak RSS %M KiB" "${@:2}"; }
cargo build --release -p hlod-builder -p engine-tools
if [ ! -s "$out/de.hlod" ]; then
  timed gen target/release/hlod-build gen plant --seed "$seed" --objects 127000 \
    --triangles 82000000 -o "$out/de.glb"
  timed build target/release/hlod-build build -q "$out/de.glb" -o "$out/de.hlod"
  rm -f "$out/de.glb"
fi
IFS=, read -ra kind_list <<< "$kinds"
IFS=, read -ra disk_list <<< "$disks"
for kind in "${kind_list[@]}"; do
  for disk in "${disk_list[@]}"; do
    timed "bench $kind $disk" target/release/hlod-bench "$out/de.hlod" --path-kind "$kind" \
      --frames "$frames" --disk "$disk" --budgets 0.6%,1.2%,2.5%,5% --render-rate 10e6 \
      --warmup 30 --tolerance 2 --out "$out/$kind-$disk"
    cat "$out/$kind-$disk/summary.md"
  done
done
