#!/usr/bin/env bash
# A scene walked over HTTP (not in CI): nginx serves the scene's folder (scripts/serve.sh),
# latency-proxy adds a round-trip time per request in front of it (this kernel has no netem),
# and hlod-bench walks each path kind from the local file (incore, nopre, pre), then nopre and pre over
# HTTP at each RTT, then twice through a disk cache at the last RTT (the first visit fills
# it, the second reads from it). With MBIT=N in the environment, every RTT is also walked through
# a link of N Mbit/s shared by its requests (the proxy's own cap, which needs no root, unlike tc tbf).
# With S3=1, moto's S3 server (target/moto-venv, from scripts/setup.sh) takes nginx's place: the scene
# is published into a bucket with `hlod-build publish` and walked as s3://scenes/NAME.hlod, through the
# same proxies (credentials and endpoint from the environment, as a user would give them).
# Tables go to out/remote/NAME/; summary.md gathers them.
# Usage: scripts/bench-remote.sh SCENE BUDGET [PATH-KINDS] [RTTS-MS] [FRAMES] [hlod-bench options…]
#   scripts/bench-remote.sh de2.hlod 7.5% flythrough,approach-orbit 0,20,50,100 300
#   scripts/bench-remote.sh schep10.hlod 2.5% flythrough,approach-orbit 0,20,50,100 300 --occlusion 0.1
set -euo pipefail
cd "$(dirname "$0")/.."
[ $# -ge 2 ] || { sed -n 2,9p "$0" >&2; exit 2; }
scene=$(realpath "$1")
budget=$2
kinds=${3:-flythrough,approach-orbit}
rtts=${4:-0,20,50,100}
frames=${5:-300}
extra=("${@:6}")
name=$(basename "$scene" .hlod)
out="out/remote/${OUT_NAME:-$name}"
mkdir -p "$out"
cargo build --release -q -p engine-tools --bin hlod-bench -p e2e-tests --bin latency-proxy \
  -p hlod-builder --bin hlod-build
port=$((18000 + RANDOM % 1000))
if [ "${S3:-0}" = 1 ]; then
  venv=target/moto-venv/bin
  [ -x "$venv/moto_server" ] || { echo "bench-remote: S3=1 needs scripts/setup.sh's moto" >&2; exit 2; }
  "$venv/moto_server" -H 127.0.0.1 -p "$port" > "$out/moto.log" 2>&1 &
  pids=($!)
  export AWS_ACCESS_KEY_ID=testing AWS_SECRET_ACCESS_KEY=testing AWS_REGION=us-east-1 AWS_ALLOW_HTTP=true
else
  bash scripts/serve.sh "$(dirname "$scene")" "$port" > "$out/serve.log" 2>&1 &
  pids=($!)
fi
trap 'kill "${pids[@]}" 2>/dev/null || true' EXIT
for _ in $(seq 100); do
  curl -s -o /dev/null "http://127.0.0.1:$port/" && break
  sleep 0.1
done
# The scene's URL through the proxy on port $1.
scene_url() {
  if [ "${S3:-0}" = 1 ]; then
    echo "s3://scenes/$(basename "$scene")"
  else
    echo "http://127.0.0.1:$1/$(basename "$scene")"
  fi
}
# hlod-bench's S3 endpoint is the proxy on port $1.
endpoint() { [ "${S3:-0}" = 1 ] && export AWS_ENDPOINT_URL="http://127.0.0.1:$1"; true; }
if [ "${S3:-0}" = 1 ]; then
  "$venv/python" -c "import boto3; boto3.client('s3', endpoint_url='http://127.0.0.1:$port', \
    aws_access_key_id='testing', aws_secret_access_key='testing', region_name='us-east-1').create_bucket(Bucket='scenes')"
  AWS_ENDPOINT_URL="http://127.0.0.1:$port" target/release/hlod-build publish "$scene" "$(scene_url "$port")"
fi
IFS=, read -ra kind_list <<< "$kinds"
IFS=, read -ra rtt_list <<< "$rtts"
for r in "${rtt_list[@]}"; do
  target/release/latency-proxy $((port + 1000 + r)) "$port" "$r" > /dev/null &
  pids+=($!)
  if [ -n "${MBIT:-}" ]; then
    target/release/latency-proxy $((port + 2000 + r)) "$port" "$r" "$MBIT" > /dev/null &
    pids+=($!)
  fi
done
sleep 0.5
bench() { target/release/hlod-bench "$@" --budget "$budget" --frames "$frames" "${extra[@]}"; }
summary="$out/summary.md"
echo "# $name over HTTP at $budget, $frames frames, options: ${extra[*]:-none}" > "$summary"
for kind in "${kind_list[@]}"; do
  bench "$scene" --path-kind "$kind" --modes incore,nopre,pre --out "$out/$kind/local" > /dev/null
  { echo; echo "## $kind: the local file"; cat "$out/$kind/local/summary.md"; } >> "$summary"
  for r in "${rtt_list[@]}"; do
    endpoint $((port + 1000 + r))
    url=$(scene_url $((port + 1000 + r)))
    bench "$url" --path-kind "$kind" --modes nopre,pre --out "$out/$kind/rtt$r" > /dev/null
    { echo; echo "## $kind: RTT $r ms"; cat "$out/$kind/rtt$r/summary.md"; } >> "$summary"
    if [ -n "${MBIT:-}" ]; then
      endpoint $((port + 2000 + r))
      url=$(scene_url $((port + 2000 + r)))
      bench "$url" --path-kind "$kind" --modes nopre,pre --out "$out/$kind/rtt$r-${MBIT}mbit" > /dev/null
      { echo; echo "## $kind: RTT $r ms, $MBIT Mbit/s"; cat "$out/$kind/rtt$r-${MBIT}mbit/summary.md"; } >> "$summary"
    fi
  done
  r=${rtt_list[-1]}
  endpoint $((port + 1000 + r))
  url=$(scene_url $((port + 1000 + r)))
  rm -rf "$out/$kind/cache-dir"
  for visit in first second; do
    bench "$url" --path-kind "$kind" --modes pre --disk-cache "$out/$kind/cache-dir" \
      --out "$out/$kind/cache-$visit" > /dev/null
    { echo; echo "## $kind: RTT $r ms, disk cache, $visit visit"; cat "$out/$kind/cache-$visit/summary.md"; } >> "$summary"
  done
  rm -rf "$out/$kind/cache-dir"
done
echo "bench-remote: $summary"
