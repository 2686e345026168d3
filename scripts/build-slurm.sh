#!/usr/bin/env bash
# A sharded build on a Slurm cluster: the N shard jobs as one job array, the
# merge as a job that runs only when every shard has succeeded (afterok), then
# each job's state, time and peak memory from `sacct`.
#
#   scripts/build-slurm.sh [OPTIONS] MODEL N OUT [-- BUILD_OPTIONS...]
#
#   --mem SIZE        memory per shard job and for the merge (sbatch --mem, e.g. 4G);
#                     hlod-build gets --memory-limit at 7/8 of it
#   --cpus N          CPUs per shard job (default 1; the build uses that many threads)
#   --partition P     the partition to submit to
#   --work DIR        where the job scripts, shard files and logs go
#                     (default OUT.slurm/); must be on storage every node reads
#   --resume          submit only the shards whose file is missing (after a
#                     failure), then the merge
#   --no-wait         submit and print the job ids, do not wait
#
# BUILD_OPTIONS (e.g. --branching 8) go to every shard job and to the merge.
# MODEL, OUT and the work folder must be readable and writable from every node.
# hlod-build is $HLOD_BUILD, else the one on PATH, else this checkout's
# target/release/hlod-build. Exits 0 when the scene is written; non-zero, naming
# each failed shard and its log, when a shard or the merge failed.
set -euo pipefail

die() {
  echo "build-slurm: $*" >&2
  exit 2
}
mem="" cpus=1 partition="" work="" resume=0 wait=1
while [ $# -gt 0 ]; do
  case "$1" in
  --mem) mem="${2:?--mem needs a size}"; shift 2 ;;
  --cpus) cpus="${2:?--cpus needs a number}"; shift 2 ;;
  --partition) partition="${2:?--partition needs a name}"; shift 2 ;;
  --work) work="${2:?--work needs a folder}"; shift 2 ;;
  --resume) resume=1; shift ;;
  --no-wait) wait=0; shift ;;
  --) break ;;
  -*) die "unknown option $1" ;;
  *) break ;;
  esac
done
[ $# -ge 3 ] || die "usage: $0 [--mem SIZE] [--cpus N] [--partition P] [--work DIR] [--resume] [--no-wait] MODEL N OUT [-- BUILD_OPTIONS...]"
model="$1" n="$2" out="$3"
shift 3
if [ $# -gt 0 ]; then
  [ "$1" = "--" ] || die "build options go after --, got '$1'"
  shift
fi
extra=("$@")
[[ "$n" =~ ^[1-9][0-9]*$ ]] || die "N must be a positive number of shards, got '$n'"
[[ "$cpus" =~ ^[1-9][0-9]*$ ]] || die "--cpus must be a positive number, got '$cpus'"
[ -r "$model" ] || die "cannot read the model $model"
for tool in sbatch squeue sacct; do
  command -v "$tool" >/dev/null 2>&1 || die "$tool not found: this needs a Slurm client (scripts/slurm-local.sh starts a cluster here)"
done

abs() { (cd "$(dirname "$1")" && printf '%s/%s' "$(pwd)" "$(basename "$1")"); }
model="$(abs "$model")"
mkdir -p "$(dirname "$out")"
out="$(abs "$out")"
work="${work:-$out.slurm}"
mkdir -p "$work/logs"
work="$(cd "$work" && pwd)"
bin="${HLOD_BUILD:-$(command -v hlod-build || true)}"
[ -n "$bin" ] || bin="$(cd "$(dirname "$0")/.." && pwd)/target/release/hlod-build"
[ -x "$bin" ] || die "no hlod-build at '$bin' (set HLOD_BUILD or build it: cargo build --release -p hlod-builder)"
bin="$(abs "$bin")"

limit=()
if [ -n "$mem" ]; then
  [[ "$mem" =~ ^([0-9]+)([KMGT]?)$ ]] || die "--mem must be a size like 4G or 512M, got '$mem'"
  num="${BASH_REMATCH[1]}" unit="${BASH_REMATCH[2]:-M}" # sbatch's default unit is MiB
  case "$unit" in K) kib=$num ;; M) kib=$((num * 1024)) ;; G) kib=$((num * 1024 * 1024)) ;; T) kib=$((num * 1024 * 1024 * 1024)) ;; esac
  limit=(--memory-limit "$((kib * 7 / 8 / 1024))M")
fi
q() {
  local a
  for a in "$@"; do printf '%q ' "$a"; done
}

# The job scripts are kept in the work folder, so a shard can be resubmitted by
# hand (sbatch --array=I shards.sbatch) as well as with --resume.
cat >"$work/shards.sbatch" <<EOF
#!/bin/bash
#SBATCH --job-name=hlod-shard
#SBATCH --output=$work/logs/shard-%a.log
#SBATCH --cpus-per-task=$cpus
set -euo pipefail
export RAYON_NUM_THREADS=\${SLURM_CPUS_PER_TASK:-$cpus}
i=\$SLURM_ARRAY_TASK_ID
exec $(q "$bin") build $(q "$model") --shard "\$i/$n" $(q "${limit[@]}" "${extra[@]}")-q -o "$work/s-\$i.hlsh"
EOF
shard_files=""
for i in $(seq 0 $((n - 1))); do shard_files+="$(q "$work/s-$i.hlsh")"; done
cat >"$work/merge.sbatch" <<EOF
#!/bin/bash
#SBATCH --job-name=hlod-merge
#SBATCH --output=$work/logs/merge.log
#SBATCH --cpus-per-task=$cpus
set -euo pipefail
export RAYON_NUM_THREADS=\${SLURM_CPUS_PER_TASK:-$cpus}
exec $(q "$bin") merge $(q "$model") $(q "${limit[@]}" "${extra[@]}")-q -o $(q "$out") $shard_files
EOF

todo=()
for i in $(seq 0 $((n - 1))); do
  if [ "$resume" = 1 ] && [ -s "$work/s-$i.hlsh" ]; then continue; fi
  todo+=("$i")
done
common=()
[ -n "$mem" ] && common+=(--mem "$mem")
[ -n "$partition" ] && common+=(--partition "$partition")
started="$(date +%s)"
if [ ${#todo[@]} -gt 0 ]; then
  array="$(
    IFS=,
    echo "${todo[*]}"
  )"
  echo "build-slurm: submitting shards $array of $n"
  shards_job="$(sbatch --parsable "${common[@]}" --array="$array" "$work/shards.sbatch")"
  shards_job="${shards_job%%;*}"
  merge_job="$(sbatch --parsable "${common[@]}" --dependency="afterok:$shards_job" --kill-on-invalid-dep=yes "$work/merge.sbatch")"
else
  echo "build-slurm: every shard file is there; submitting the merge only"
  shards_job=""
  merge_job="$(sbatch --parsable "${common[@]}" "$work/merge.sbatch")"
fi
merge_job="${merge_job%%;*}"
echo "build-slurm: shards job ${shards_job:-none}, merge job $merge_job, work folder $work"
[ "$wait" = 1 ] || exit 0

ids="$merge_job${shards_job:+,$shards_job}"
while [ -n "$(squeue -h -j "$ids" -o %i 2>/dev/null)" ]; do sleep 1; done

# Accounting may lag the end of the last job by a moment.
acct=""
for _ in $(seq 20); do
  acct="$(sacct -n -P -j "$ids" --format=JobID,State,ExitCode,Elapsed,MaxRSS,TotalCPU 2>/dev/null || true)"
  if [ -n "$acct" ] && ! grep -qE '\|(PENDING|RUNNING|COMPLETING)\|' <<<"$acct"; then break; fi
  sleep 0.5
done
[ -n "$acct" ] || echo "build-slurm: sacct reports nothing (is accounting enabled?); judging by the files" >&2

field() { # JOBID COLUMN -> the value in sacct's line for that job or step
  awk -F'|' -v id="$1" -v c="$2" '$1 == id { print $c; exit }' <<<"$acct"
}
failed=()
printf '%-10s %-12s %-9s %-10s %-12s %s\n' job state exit elapsed "CPU time" "peak RSS"
for i in "${todo[@]}"; do
  [ -n "$shards_job" ] || break
  id="${shards_job}_$i"
  state="$(field "$id" 2)"
  printf '%-10s %-12s %-9s %-10s %-12s %s\n' "shard $i" "${state:-?}" "$(field "$id" 3)" "$(field "$id" 4)" "$(field "$id" 6)" "$(field "$id.batch" 5)"
  if [ -n "$acct" ]; then
    [ "$state" = COMPLETED ] || failed+=("$i")
  else
    [ -s "$work/s-$i.hlsh" ] || failed+=("$i")
  fi
done
mstate="$(field "$merge_job" 2)"
printf '%-10s %-12s %-9s %-10s %-12s %s\n' merge "${mstate:-?}" "$(field "$merge_job" 3)" "$(field "$merge_job" 4)" "$(field "$merge_job" 6)" "$(field "$merge_job.batch" 5)"

if [ ${#failed[@]} -gt 0 ]; then
  for i in "${failed[@]}"; do
    echo "build-slurm: shard $i of $n failed ($(field "${shards_job}_$i" 2), exit $(field "${shards_job}_$i" 3)); its log: $work/logs/shard-$i.log" >&2
  done
  echo "build-slurm: the merge did not run; $out not written. Resubmit the failed shards with: $0 --resume ${mem:+--mem $mem }$model $n $out${extra[*]:+ -- ${extra[*]}}" >&2
  exit 1
fi
if { [ -n "$acct" ] && [ "$mstate" != COMPLETED ]; } || [ ! -s "$out" ]; then
  echo "build-slurm: the merge failed (${mstate:-no state}); its log: $work/logs/merge.log" >&2
  exit 1
fi
echo "build-slurm: wrote $out ($(($(date +%s) - started)) s from submission to the merge's end)"
