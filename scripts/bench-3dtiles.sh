#!/usr/bin/env bash
# Our runtime and a 3D Tiles viewer on the same scene and path (not in CI).
# The scene's folder and its 3D Tiles export are served by nginx on this
# machine; hlod-bench walks a generated path over HTTP (`pre` mode, the
# `none` renderer at 10M triangles/s, at BUDGET); then 3DTilesRendererJS, in
# headless Chromium (WebGL on SwiftShader), walks the same path through the
# export with its tile cache capped at the same bytes and its error target at
# the same ε, in real time (viewer/web/walk.mjs). summary.md has one table,
# resident.svg the resident bytes of both along the path.
# WALK_TIMEOUT (seconds, default 3600) bounds the browser's wait for its
# first complete view; PARSE_JOBS (default 5, the library's) sets the page's
# parses per frame. BUNDLE (a size such as 256K; default 0, a tile per rep)
# exports with `--bundle`.
# Usage: scripts/bench-3dtiles.sh SCENE BUDGET [PATH-KIND] [FRAMES] [SIZE]
#   scripts/bench-3dtiles.sh de2.hlod 7.5% flythrough 300 640x360
set -euo pipefail
cd "$(dirname "$0")/.."
[ $# -ge 2 ] || { sed -n 2,14p "$0" >&2; exit 2; }
scene=$(realpath "$1")
budget=$2
kind=${3:-flythrough}
frames=${4:-300}
size=${5:-640x360}
eps=2
name=$(basename "$scene" .hlod)
out="out/3dtiles/$name/$kind"
mkdir -p "$out"
cargo build --release -q -p engine-tools --bin hlod-bench -p hlod-builder --bin hlod-build
bundle=${BUNDLE:-0}
tiles="out/3dtiles/$name/tiles"
if [ "$bundle" != 0 ]; then
  tiles="$tiles-b$bundle"
  out="$out-b$bundle"
  mkdir -p "$out"
fi
if ! [ -f "$tiles/tileset.json" ] || [ "$scene" -nt "$tiles/tileset.json" ]; then
  /usr/bin/time -f "export: %e s, peak RSS %M KiB" target/release/hlod-build export-3dtiles "$scene" -o "$tiles" --bundle "$bundle" 2>&1 | tee "$out/export.txt"
fi
port=$((19000 + RANDOM % 500))
bash scripts/serve.sh "$(dirname "$scene")" "$port" > "$out/serve.log" 2>&1 &
pids=($!)
bash scripts/serve-web.sh "$tiles" $((port + 500)) > "$out/serve-web.log" 2>&1 &
pids+=($!)
trap 'kill "${pids[@]}" 2>/dev/null || true' EXIT
sleep 1
w=${size%x*}
h=${size#*x}
target/release/hlod-bench "http://127.0.0.1:$port/$(basename "$scene")" --path-kind "$kind" \
  --frames "$frames" --modes pre --budget "$budget" --render-rate 10e6 --tolerance "$eps" \
  --width "$w" --height "$h" --out "$out/ours" > "$out/ours.log"
# The same bytes as the tile cache's cap.
cap=$(awk -F, 'NR == 2 { print $14 }' "$out/ours/pre.csv")
cp viewer/web/walk.mjs viewer/web/browser.mjs target/web/
node target/web/walk.mjs "http://127.0.0.1:$((port + 500))/?error=$eps&cache=$(awk "BEGIN { print $cap / 1048576 }")&parse=${PARSE_JOBS:-5}" \
  --path "$out/ours/path.txt" --size "$size" --fps 30 --out "$out/theirs.csv" \
  --timeout "${WALK_TIMEOUT:-3600}" > "$out/theirs.json"
mib() { awk "BEGIN { printf \"%.1f\", $1 / 1048576 }"; }
# Ours: bytes over the network (the summary's table), resident, frames with a missing rep.
fetched=$(awk -F'|' '/\| run \| requests/ { f = 1 } f && /^\| pre \|/ { gsub(/ /, "", $4); print $4; exit }' "$out/ours/summary.md")
# A frame is incomplete when it drew an ancestor for a missing rep.
ours=$(awk -F, 'NR > 1 { n++; t += $3; if ($16 > 0) inc++; if ($12 > mx) mx = $12;
  if (!done && $16 == 0) { first = t; done = 1 } }
  END { printf "%d|%d|%.1f|%.0f", n, inc, mx / 1048576, first }' "$out/ours/pre.csv")
theirs=$(awk -F, 'NR > 1 { n++; if ($4 == 0) inc++; if ($5 > mx) mx = $5; dl = $6 }
  END { printf "%d|%d|%.1f|%.1f", n, inc, mx / 1048576, dl / 1048576 }' "$out/theirs.csv")
first=$(sed -n 's/.*"firstCompleteMs":\([0-9]*\).*/\1/p' "$out/theirs.json")
IFS='|' read -r on oi om ofirst <<< "$ours"
IFS='|' read -r tn ti tm tdl <<< "$theirs"
{
  echo "# $name, $kind, $frames poses at 30 fps, $size, ε $eps px, cap $(mib "$cap") MiB"
  echo
  echo "| runtime | frames drawn | incomplete frames | max resident / cached MiB | MiB downloaded | first complete view (ms) |"
  echo "|---|---:|---:|---:|---:|---:|"
  echo "| ours (pre, over HTTP) | $on | $oi | $om | $fetched | $ofirst |"
  echo "| 3DTilesRendererJS (Chromium, SwiftShader) | $tn | $ti | $tm | $tdl | $first |"
} > "$out/summary.md"
python3 scripts/resident-plot.py "$out/ours/pre.csv" "$out/theirs.csv" "$cap" "$out/resident.svg" \
  "$name, $kind: resident bytes along the path (cap $(mib "$cap") MiB)"
cat "$out/summary.md"
echo "resident bytes along the path: $out/resident.svg"
