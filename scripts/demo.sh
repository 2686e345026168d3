#!/usr/bin/env bash
# The main job: set-up, build, generate the demo plant, build its out-of-core scene,
# validate it, and walk the committed camera path in-core and out-of-core (with and
# without prefetching) with the wgpu renderer (lavapipe without a GPU) at a footprint of
# 8% of the data (about twice the largest front, the paper's Power-Plant ratio) on the
# `hdd` disk model, after showing the first view for a second as a viewer does (start-up
# reported apart); prints the table, the image quality against in-core, and the plots;
# then builds the bundled bunny's view-dependence tree and compares Virt. and Ext. on it.
# Usage: scripts/demo.sh [TRIANGLES] (default 3,000,000; the committed path fits the default).
set -euo pipefail
cd "$(dirname "$0")/.."
tris="${1:-3000000}"
out=out/demo
mkdir -p "$out"
t0=$(date +%s%N)
bash scripts/setup.sh
# Mesa wants a private runtime directory (else it warns on every adapter start).
if [ -z "${XDG_RUNTIME_DIR:-}" ]; then
  export XDG_RUNTIME_DIR="$(mktemp -d)"
  chmod 700 "$XDG_RUNTIME_DIR"
fi
t1=$(date +%s%N)
cargo build --release --workspace
t2=$(date +%s%N)
target/release/hlod-build gen plant --seed 1 --objects 1200 --triangles "$tris" -o "$out/plant.glb"
t3=$(date +%s%N)
target/release/hlod-build build "$out/plant.glb" -o "$out/plant.hlod"
target/release/hlod-build info "$out/plant.hlod"
t4=$(date +%s%N)
path_arg=()
if [ "$tris" = 3000000 ]; then path_arg=(--path paths/demo-flythrough.txt); fi
target/release/hlod-bench "$out/plant.hlod" "${path_arg[@]}" --modes incore,nopre,pre \
  --budget 8% --disk hdd --renderer wgpu --psnr-every 30 --fps 30 --warmup 30 --out "$out/bench"
t5=$(date +%s%N)
# View-dependence trees: the bundled bunny's tree, refined along its committed path by the
# virtual-memory baseline and the external-memory meta-node store (El-Sana & Chiang Table 2).
target/release/hlod-build vdt tests/data/bunny.glb -o "$out/bunny.vdt"
target/release/vdt-bench "$out/bunny.vdt" --path paths/vdt-bunny.txt --budgets 80%,120% \
  --disk ssd --psnr-every 60 --out "$out/vdt"
# The same tree as the bunny's finest rep in a scene (two static LODs kept), walked by the
# out-of-core runtime with the wgpu renderer: P_R refines and draws it under the one footprint.
target/release/hlod-build build tests/data/bunny.glb -o "$out/bunny-vdt.hlod" --vdt-tris 50000
target/release/hlod-bench "$out/bunny-vdt.hlod" --path paths/vdt-bunny.txt --modes incore,pre \
  --budget 7MiB --vdt-pool 3MiB --tolerance 1 --disk ssd --renderer wgpu --psnr-every 60 \
  --out "$out/vdt-scene"
t6=$(date +%s%N)
echo
echo "scene: $out/plant.hlod"
echo "plots: $out/bench/frame_time.png, stage2_vs_front.png, resident.png; per-frame CSVs and summary.md beside them"
echo "view-dependence trees: $out/vdt/table2.md, frames.csv, psnr.csv; in the scene graph: $out/vdt-scene/summary.md"
secs() { local ms=$(( ($2 - $1) / 1000000 )); printf '%d.%01d s' $((ms / 1000)) $(((ms % 1000) / 100)); }
echo "time: set-up $(secs "$t0" "$t1"), cargo build $(secs "$t1" "$t2"), generate $(secs "$t2" "$t3"), HLOD build + validate $(secs "$t3" "$t4"), walkthrough $(secs "$t4" "$t5"), view-dependence tree $(secs "$t5" "$t6"), total $(secs "$t0" "$t6")"
