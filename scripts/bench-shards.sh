#!/usr/bin/env bash
# Split + merge against the single job (not in CI): generates a plant, builds it as one job, then
# as N shard jobs run concurrently on this machine and one merge, checks that the two scenes are
# byte-identical, validates the merged one and walks it. Each step's wall time and peak RSS are
# printed (`/usr/bin/time`); the shards' own figures go to out/shards/.
# The input is written as .gltf + .bin, which has no size limit (GLB stops at 4 GiB).
# Usage: scripts/bench-shards.sh [SEED] [OBJECTS] [TRIANGLES] [SHARDS] [MEMORY-LIMIT]
#   defaults: 2 127000 82000000 4 2G   (the Double-Eagle-size plant; 4 shards of at most 2 GiB)
set -euo pipefail
cd "$(dirname "$0")/.."
seed="${1:-2}"
objects="${2:-127000}"
tris="${3:-82000000}"
n="${4:-4}"
limit="${5:-2G}"
out="out/shards/seed$seed-$objects-$tris"
mkdir -p "$out"
timed() { /usr/bin/time -f "$1: %e s, peak RSS %M KiB" "${@:2}"; }
cargo build --release -p hlod-builder -p engine-tools
bin=target/release/hlod-build
[ -s "$out/in.gltf" ] || timed gen "$bin" gen plant --seed "$seed" --objects "$objects" \
  --triangles "$tris" -o "$out/in.gltf"
timed single "$bin" build -q "$out/in.gltf" -o "$out/single.hlod" --memory-limit "$limit"
rm -f "$out"/s-*.hlsh
start=$(date +%s%N)
pids=()
for ((i = 0; i < n; i++)); do
  timed "shard $i/$n" "$bin" build -q "$out/in.gltf" --shard "$i/$n" --memory-limit "$limit" \
    -o "$out/s-$i.hlsh" 2> "$out/shard-$i.log" &
  pids+=($!)
done
for p in "${pids[@]}"; do wait "$p"; done
shards_end=$(date +%s%N)
cat "$out"/shard-*.log
timed merge "$bin" merge "$out/in.gltf" "$out"/s-*.hlsh -o "$out/merged.hlod"
end=$(date +%s%N)
ms() { echo "$(( ($1 - start) / 1000000 )) ms"; }
echo "shards (concurrent): $(ms "$shards_end"); shards + merge: $(ms "$end")"
du -b "$out"/s-*.hlsh "$out/single.hlod" "$out/merged.hlod"
cmp "$out/single.hlod" "$out/merged.hlod" && echo "merged = single job: byte-identical"
timed info "$bin" info "$out/merged.hlod" | tail -3
timed walk target/release/hlod-bench "$out/merged.hlod" --path-kind flythrough --frames 300 \
  --disk ssd --budgets 1.2% --render-rate 10e6 --warmup 30 --tolerance 2 --modes nopre,pre \
  --out "$out/walk"
cat "$out/walk/summary.md"
