#!/usr/bin/env bash
# Where the fronts' triangles go (issue 45's diagnosis; not in CI): generates and builds the
# PP-size plant (seeds 1, 2), the DE-size plant (seeds 2, 3) and the 10x10 tilings of the
# Schependomlaan and the Duplex, then runs `hlod-bench --anatomy 1,2,3` on two path kinds each
# (plants: flythrough and approach-orbit; buildings: interior and flythrough), 600 frames at
# 1280x720, every 20th frame rasterised on the CPU. Tables go to out/anatomy/*/anatomy.md,
# collected in out/anatomy/summary.md.
# About 6 GiB of disk while the DE-size GLBs exist, 1.3 GiB peak RSS; about 25 minutes on 2 cores.
# WITH_777=1 adds the 777 class (300 frames per path; 14 GiB of disk while its input exists,
# 2.8 GiB peak RSS building under a 4 GiB limit, about 13 minutes more).
# Usage: [WITH_777=1] scripts/anatomy.sh [SCENES-DIR] [TOLERANCES]   (defaults: out/scenes 1,2,3)
set -euo pipefail
cd "$(dirname "$0")/.."
dir="${1:-out/scenes}"
tols="${2:-1,2,3}"
out=out/anatomy
mkdir -p "$dir" "$out"
cargo build --release -p hlod-builder -p engine-tools
B=target/release
plant() { # name seed objects triangles
  if [ ! -s "$dir/$1.hlod" ]; then
    $B/hlod-build gen plant --seed "$2" --objects "$3" --triangles "$4" -o "$dir/$1.glb"
    $B/hlod-build build -q "$dir/$1.glb" -o "$dir/$1.hlod"
    rm -f "$dir/$1.glb"
  fi
}
tiled() { # name source
  if [ ! -s "$dir/$1.hlod" ]; then
    $B/hlod-build gen tile "../shared/data/$2.glb" --grid 10x10 --baked -o "$dir/$1.glb"
    $B/hlod-build build -q "$dir/$1.glb" -o "$dir/$1.hlod"
    rm -f "$dir/$1.glb"
  fi
}
plant pp1 1 1200 13000000
plant pp2 2 1200 13000000
plant de2 2 127000 82000000
plant de3 3 127000 82000000
if [ "${WITH_777:-0}" = 1 ] && [ ! -s "$dir/b777.hlod" ]; then
  $B/hlod-build gen plant --seed 1 --objects 700000 --triangles 350000000 -o "$dir/b777.gltf"
  $B/hlod-build build -q --memory-limit 4G "$dir/b777.gltf" -o "$dir/b777.hlod"
  rm -f "$dir/b777.gltf" "$dir/b777.bin"
fi
tiled schep10 schependomlaan_subcontractors
tiled duplex10 Ifc2x3_Duplex_Architecture
summary="$out/summary.md"
: > "$summary"
scenes="pp1 pp2 de2 de3"
[ "${WITH_777:-0}" = 1 ] && scenes="$scenes b777"
for scene in $scenes schep10 duplex10; do
  case "$scene" in
    schep* | duplex*) kinds="rooms flythrough" ;;
    *) kinds="flythrough approach-orbit" ;;
  esac
  for kind in $kinds; do
    o="$out/$scene-$kind"
    frames=600
    [ "$scene" = b777 ] && frames=300
    $B/hlod-bench "$dir/$scene.hlod" --path-kind "$kind" --seed 1 --frames "$frames" \
      --anatomy "$tols" --anatomy-every 20 --out "$o" > /dev/null
    { echo "### $scene, $kind"; echo; cat "$o/anatomy.md"; echo; } >> "$summary"
  done
done
cat "$summary"
