#!/usr/bin/env bash
# Soak (not run by CI): FRAMES frames per mode (default 10^5) on random
# paths (hlod-bench --path-kind random: random walks with jumps and random
# fields of view) with random budgets, stall deadlines and disk models, over
# RUNS runs (default 3) on a generated plant. hlod-bench fails a run whose
# footprint exceeds its budget on any frame; each run's peak RSS comes from
# /usr/bin/time, each mode's resident and peak memory from the run's log.
#
#   bash scripts/soak.sh [FRAMES] [RUNS]
set -euo pipefail
cd "$(dirname "$0")/.."
frames=${1:-100000}
runs=${2:-3}
bash scripts/setup.sh
command -v /usr/bin/time >/dev/null 2>&1 || { apt-get update -qq && apt-get install -y -qq time; }
cargo build --release --quiet -p engine-tools -p hlod-builder
bin=target/release
out=out/soak
mkdir -p "$out"
[ -f "$out/plant.hlod" ] || {
  "$bin/hlod-build" gen plant --seed 5 --objects 300 --triangles 400000 -o "$out/plant.glb"
  "$bin/hlod-build" build "$out/plant.glb" -o "$out/plant.hlod" -q
}
printf '| run | seed | budget | disk | stall ms | wall s | peak RSS MiB | violations | per mode (RSS at end, peak) |\n|---|---:|---:|---|---:|---:|---:|---:|---|\n' > "$out/soak.md"
for r in $(seq 1 "$runs"); do
  seed=$((r * 7919))
  # Deterministic "random" choices from the seed.
  budget=$(awk -v s="$seed" 'BEGIN { srand(s); printf "%.2f%%", 0.5 + rand() * 19.5 }')
  disk=$(awk -v s="$seed" 'BEGIN { srand(s + 1); split("file nvme ssd", d, " "); print d[1 + int(rand() * 3)] }')
  stall=$(awk -v s="$seed" 'BEGIN { srand(s + 2); print (rand() < 0.5) ? 0 : 5 }')
  dir="$out/run$r"
  set +e
  /usr/bin/time -v "$bin/hlod-bench" "$out/plant.hlod" --path-kind random --seed "$seed" \
    --frames "$frames" --fps 0 --budget "$budget" --disk "$disk" --stall-deadline "$stall" \
    --tolerance 2 --out "$dir" > "$dir.log" 2>&1
  status=$?
  set -e
  rss_kib=$(awk -F': ' '/Maximum resident set size/ { print $2 }' "$dir.log")
  wall=$(awk -F': ' '/Elapsed \(wall clock\)/ { print $2 }' "$dir.log")
  violations=0
  [ "$status" -eq 0 ] || violations=$(grep -c "exceeded the budget" "$dir.log" || true)
  modes=$(grep -E ': done \(' "$dir.log" | sed 's/: done (/ (/' | paste -sd ';' -)
  rss_mib=$(awk -v k="${rss_kib:-0}" 'BEGIN { printf "%.0f", k / 1024 }')
  printf '| %s | %s | %s | %s | %s | %s | %s | %s | %s |\n' "$r" "$seed" "$budget" "$disk" \
    "$stall" "$wall" "$rss_mib" "$violations" "$modes" >> "$out/soak.md"
  if [ "$status" -ne 0 ]; then
    echo "soak: run $r failed (exit $status); see $dir.log" >&2
    cat "$out/soak.md"
    exit 1
  fi
done
cat "$out/soak.md"
