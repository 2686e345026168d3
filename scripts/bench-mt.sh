#!/usr/bin/env bash
# Multi-Triangulation benchmarks (docs/results.md, "Multi-Triangulations"):
#  1. Holst & Schumann's Figs 4-5: the four caching modes on a far-to-near
#     and a rotating path, for the bunny, the dragon and a generated 1M-triangle
#     rock (mt-bench; I/O counts and memory are deterministic);
#  2. θ, the partition size, swept on the rock;
#  3. the MT against the view-dependence tree as a large object's finest rep:
#     same objects, paths, ε, footprint and disk model (hlod-bench), twice
#     each for the spread, and image quality against the full-resolution
#     mesh (hlod-bench --fidelity, wgpu; lavapipe without a GPU).
# Usage: scripts/bench-mt.sh [DATA_DIR (default ../shared/data)] [OUT (default out/mt)]
set -euo pipefail
cd "$(dirname "$0")/.."
data=${1:-../shared/data}
out=${2:-out/mt}
mkdir -p "$out"
cargo build --release -q -p hlod-builder -p engine-tools
B=target/release
[ -f "$out/rock.glb" ] || $B/hlod-build gen rock --tris 1000000 --seed 1 -o "$out/rock.glb"
cp -f "$data/bunny.glb" "$data/dragon.glb" "$out/"
for m in bunny dragon rock; do
  $B/hlod-build mt "$out/$m.glb" --theta 20 -o "$out/$m.mt" | tee "$out/build-$m.md"
done
$B/mt-bench "$out/bunny.mt" "$out/dragon.mt" "$out/rock.mt" --paths far-near,rotate --out "$out/figs"
for t in 5 20 64 200; do
  $B/hlod-build mt "$out/rock.glb" --theta $t -o "$out/rock-t$t.mt" > /dev/null
  $B/mt-bench "$out/rock-t$t.mt" --modes p-c,p-cc --out "$out/theta-$t"
done
if [ -z "${XDG_RUNTIME_DIR:-}" ]; then
  export XDG_RUNTIME_DIR="$(mktemp -d)"
  chmod 700 "$XDG_RUNTIME_DIR"
fi
for m in dragon rock; do
  $B/hlod-build build "$out/$m.glb" -o "$out/$m-mt.hlod" --mt-tris 100000 -q
  $B/hlod-build build "$out/$m.glb" -o "$out/$m-vdt.hlod" --vdt-tris 100000 -q
  for k in mt vdt; do
    for p in approach-orbit orbit; do
      for run in 1 2; do
        $B/hlod-bench "$out/$m-$k.hlod" --path-kind $p --frames 300 --budget 64MiB --vdt-pool 32MiB \
          --disk ssd --fps 0 --modes nopre --out "$out/cmp/$m-$k-$p-$run" > "$out/cmp-$m-$k-$p-$run.md"
      done
    done
    $B/hlod-bench "$out/$m-$k.hlod" --path-kind approach-orbit --frames 120 --fidelity 1,2,3 \
      --renderer wgpu --psnr-every 20 --width 640 --height 360 --fps 0 --out "$out/fid/$m-$k" \
      > "$out/fid-$m-$k.md"
  done
done
echo "bench-mt: results under $out"
