#!/usr/bin/env bash
# Fuzz campaign (cargo-fuzz, nightly): runs each target of tests/fuzz for
# RUNS executions (default 10^7), seeded with tests/fuzz/seeds/TARGET and
# keeping its corpus in target/fuzz-corpus/TARGET. A crash, a panic, a
# sanitizer report, a time-out (10 s) or an allocation beyond 2 GiB stops the
# target and leaves the input in tests/fuzz/artifacts/TARGET/; it becomes a
# regression test. Not run by CI (its seeds and regressions run in cargo test);
# `FUZZ_SMOKE=1 bash scripts/test.sh` adds a short smoke run.
#
#   bash scripts/fuzz.sh [RUNS]            all seven targets, one after another
#   TARGETS="gltf_import" bash scripts/fuzz.sh 100000
#   SEED=1 bash scripts/fuzz.sh 20000      reproducible (test.sh's smoke run)
set -euo pipefail
cd "$(dirname "$0")/.."
runs=${1:-10000000}
targets=${TARGETS:-"scene_reader vdt_reader gltf_import path_parser shard_reader cache_entry mesh_import"}
if ! cargo +nightly --version >/dev/null 2>&1; then
  echo "fuzz: needs the nightly toolchain (rustup toolchain install nightly)" >&2
  exit 1
fi
command -v cargo-fuzz >/dev/null 2>&1 || cargo install cargo-fuzz --locked
mkdir -p target/fuzz-logs
for t in $targets; do
  corpus="target/fuzz-corpus/$t"
  mkdir -p "$corpus"
  start=$(date +%s)
  set +e
  cargo +nightly fuzz run --fuzz-dir tests/fuzz "$t" "$corpus" "tests/fuzz/seeds/$t" -- \
    -runs="$runs" -max_len=65536 -rss_limit_mb=2048 -malloc_limit_mb=2048 -timeout=10 \
    -print_final_stats=1 ${SEED:+-seed=$SEED} 2>&1 | tee "target/fuzz-logs/$t.log" |
    grep -E "^(#[0-9]+ +(DONE|INITED)|stat::number_of_executed_units|==[0-9]+==|SUMMARY|panicked)"
  status=${PIPESTATUS[0]}
  set -e
  echo "fuzz: $t: exit $status, $(( $(date +%s) - start )) s, corpus $(ls "$corpus" | wc -l) inputs"
  if [ "$status" -ne 0 ]; then
    echo "fuzz: $t found a failure; input in tests/fuzz/artifacts/$t/" >&2
    exit "$status"
  fi
done
