#!/usr/bin/env bash
# The Boeing-777-class benchmark (not in CI): generates a plant of 700,000 objects and
# 350M triangles as .gltf + .bin (past GLB's 4 GiB), builds it under a 4 GiB memory
# limit, and walks a generated path in-core and out-of-core (with and without
# prefetching) at a 1.2% footprint on the `ssd` and `hdd` disk models (`none` renderer at
# 10M triangles/s). Each step's wall time and peak RSS are printed (`/usr/bin/time`);
# the tables go to out/777/.
# Needs about 30 GiB of disk (the input, the scene and its staging copy) and, for the
# in-core mode, memory for every rep decoded.
# Usage: scripts/bench-777.sh [SEED] [PATH-KIND] [DISKS] [FRAMES] [MEMORY-LIMIT] [MODES]
#   defaults: 1 flythrough ssd,hdd 300 4G incore,nopre,pre
#   (the in-core mode does not depend on the disk model: MODES applies to the first disk,
#   the others run nopre,pre)
set -euo pipefail
cd "$(dirname "$0")/.."
seed="${1:-1}"
kind="${2:-flythrough}"
disks="${3:-ssd,hdd}"
frames="${4:-300}"
limit="${5:-4G}"
modes="${6:-incore,nopre,pre}"
out="out/777/seed$seed"
mkdir -p "$out"
timed() { /usr/bin/time -f "$1: %e s, peak RSS %M KiB" "${@:2}"; }
cargo build --release -p hlod-builder -p engine-tools
if [ ! -s "$out/b777.hlod" ]; then
  timed gen target/release/hlod-build gen plant --seed "$seed" --objects 700000 \
    --triangles 350000000 -o "$out/b777.gltf"
  du -b "$out/b777.gltf" "$out/b777.bin"
  timed build target/release/hlod-build build -q "$out/b777.gltf" -o "$out/b777.hlod" \
    --memory-limit "$limit"
  rm -f "$out/b777.gltf" "$out/b777.bin"
fi
timed info target/release/hlod-build info --no-verify-data "$out/b777.hlod"
IFS=, read -ra disk_list <<< "$disks"
for disk in "${disk_list[@]}"; do
  timed "bench $kind $disk" target/release/hlod-bench "$out/b777.hlod" --path-kind "$kind" \
    --frames "$frames" --disk "$disk" --budgets 1.2% --render-rate 10e6 \
    --warmup 30 --tolerance 2 --modes "$modes" --out "$out/$kind-$disk"
  cat "$out/$kind-$disk/summary.md"
  modes="nopre,pre"
done
