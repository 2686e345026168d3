#!/usr/bin/env bash
# A sharded build through Slurm against one job (not in CI): starts a single-node
# cluster with accounting on this machine (scripts/slurm-local.sh; needs root), runs
# the whole build as one job, then as N shard jobs and a merge for each N in
# SHARDS (scripts/build-slurm.sh), checks each merged scene is byte-identical to the
# single job's, and prints sacct's figures (elapsed, CPU time, peak RSS) per job.
# The shards get one CPU each, the single job all of them.
# Usage: scripts/bench-slurm.sh [SEED] [OBJECTS] [TRIANGLES] [SHARDS] [MEM]
#   defaults: 1 700000 350000000 4,8 3G   (the 777 class; about 20 GiB of disk)
set -euo pipefail
cd "$(dirname "$0")/.."
seed="${1:-1}"
objects="${2:-700000}"
tris="${3:-350000000}"
shards="${4:-4,8}"
mem="${5:-3G}"
out="out/slurm/seed$seed-$objects-$tris"
mkdir -p "$out"
out="$(cd "$out" && pwd)"
cargo build --release -p hlod-builder
export HLOD_BUILD="$PWD/target/release/hlod-build"
[ -s "$out/in.gltf" ] || /usr/bin/time -f "gen: %e s, peak RSS %M KiB" "$HLOD_BUILD" gen plant \
  --seed "$seed" --objects "$objects" --triangles "$tris" -o "$out/in.gltf"
eval "$(bash scripts/slurm-local.sh start "$out/cluster")"
trap 'bash scripts/slurm-local.sh stop "$out/cluster"' EXIT
sacct_line() {
  sacct -n -P -j "$1" --format=JobID,State,Elapsed,TotalCPU,MaxRSS | tr '|' ' '
}
# The single job, all CPUs.
limit_mib=$(($(numfmt --from=iec "${mem}") * 7 / 8 / 1048576))
cpus="$(nproc)"
start=$(date +%s)
jid="$(sbatch --parsable --wait --mem "$mem" --cpus-per-task "$cpus" -o "$out/single.log" \
  --wrap "RAYON_NUM_THREADS=$cpus $HLOD_BUILD build -q $out/in.gltf -o $out/single.hlod --memory-limit ${limit_mib}M")" ||
  { echo "the single job failed:"; cat "$out/single.log"; exit 1; }
echo "single job: $(($(date +%s) - start)) s from submission"
sleep 2
echo "JobID State Elapsed TotalCPU MaxRSS"
sacct_line "$jid"
IFS=, read -ra counts <<<"$shards"
for n in "${counts[@]}"; do
  rm -rf "$out/merged-$n.hlod" "$out/merged-$n.hlod.slurm"
  bash scripts/build-slurm.sh --mem "$mem" "$out/in.gltf" "$n" "$out/merged-$n.hlod"
  du -b "$out/merged-$n.hlod.slurm"/s-*.hlsh
  cmp "$out/single.hlod" "$out/merged-$n.hlod" && echo "$n shards: merged = single job, byte-identical"
  rm -rf "$out/merged-$n.hlod" "$out/merged-$n.hlod.slurm"/s-*.hlsh
done
