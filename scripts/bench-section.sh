#!/usr/bin/env bash
# What a section or hidden elements save (issue 48, items 2 and 3; not in CI): walks the 10x10
# tilings of the Schependomlaan and the Duplex on the interior and fly-through paths (two seeds
# each) in-core and out-of-core with prefetching, without a section and with a section box that
# keeps the ground storey (from below the foundations up to TOP metres, the whole plan), or with
# the elements whose description holds a text hidden or x-rayed (VARIANTS="none hide:IfcSlab
# xray:IfcSlab"), and tabulates
# each run's front (median and largest, the footprint the view needs), frame times, Stage II
# bytes and substituted frames. Same path, same ε (2 px), same footprint (5%, `ssd`), `none`
# renderer. The scenes are built as scripts/anatomy.sh builds them (in out/scenes/).
# Table: out/section/summary.md. About 15 minutes on 2 cores.
# SCENES and KINDS choose among the scenes and path kinds (rooms, flythrough, interior: a walk
# generated on the walk section). VARIANTS="none walk" walks the paths instead (hlod-bench --walk): the walker's cost per frame
# and its walk map's bytes go to out/section/walk-lines.txt.
# Usage: [VARIANTS="none storey hide:TEXT xray:TEXT walk …"] scripts/bench-section.sh [TOP] [SEEDS]
#   [FRAMES] [BUDGET] (defaults: VARIANTS="none storey", 2.5 1,2 600 5%; tables to
#   out/section/summary.md, or summary-hide.md when a variant hides or x-rays)
set -euo pipefail
cd "$(dirname "$0")/.."
top="${1:-2.5}"
seeds="${2:-1,2}"
frames="${3:-600}"
budget="${4:-5%}"
dir=out/scenes
out=out/section
mkdir -p "$dir" "$out"
cargo build --release -p hlod-builder -p engine-tools
B=target/release
tiled() { # name source (rebuilt when it has no walk section: built before format version 5)
  if [ ! -s "$dir/$1.hlod" ] || $B/hlod-build info "$dir/$1.hlod" | grep "walk section: none" > /dev/null; then
    $B/hlod-build gen tile "../shared/data/$2.glb" --grid 10x10 --baked -o "$dir/$1.glb"
    $B/hlod-build build -q "$dir/$1.glb" -o "$dir/$1.hlod"
    rm -f "$dir/$1.glb"
  fi
}
tiled schep10 schependomlaan_subcontractors
tiled duplex10 Ifc2x3_Duplex_Architecture
# The median and the largest of a CSV column (by name) over its rows.
stats() { # file column scale
  awk -F, -v col="$2" 'NR == 1 { for (i = 1; i <= NF; i++) if ($i == col) c = i; next }
    { print $c }' "$1" | sort -g | awk -v s="$3" '{ v[NR] = $1 }
    END { m = (NR % 2) ? v[(NR + 1) / 2] : (v[NR / 2] + v[NR / 2 + 1]) / 2;
          p = v[int(NR * 0.99 + 0.999)]; printf "%.2f %.2f %.2f\n", m / s, p / s, v[NR] / s }'
}
sum() { # file column scale
  awk -F, -v col="$2" -v s="$3" 'NR == 1 { for (i = 1; i <= NF; i++) if ($i == col) c = i; next }
    { t += $c; n += ($c > 0) } END { printf "%.2f %d\n", t / s, n }' "$1"
}
variants="${VARIANTS:-none storey}"
summary="$out/summary.md"
case "$variants" in *hide:* | *xray:*) summary="$out/summary-hide.md" ;; *walk*) summary="$out/summary-walk.md"; rm -f "$out/walk-lines.txt" ;; esac
{
  echo "| scene | path | seed | section or hidden | front MiB median / max | front tris median | in-core ms median / p99 | pre ms median / p99 | Stage II MiB | frames substituted |"
  echo "|---|---|---:|---|---:|---:|---:|---:|---:|---:|"
} > "$summary"
IFS=, read -ra seed_list <<< "$seeds"
for scene in ${SCENES:-schep10 duplex10}; do
  read -r x0 y0 z0 x1 _ z1 < <($B/hlod-build info "$dir/$scene.hlod" |
    sed -n 's/.*bounds \[\(.*\)\] \.\. \[\(.*\)\], root.*/\1 \2/p' | tr -d ',')
  box="$(awk -v a="$x0" -v b="$y0" -v c="$z0" -v d="$x1" -v t="$top" -v f="$z1" \
    'BEGIN { printf "%g,%g,%g,%g,%g,%g", a - 1, b - 1, c - 1, d + 1, t, f + 1 }')"
  for kind in ${KINDS:-rooms flythrough}; do
    for seed in "${seed_list[@]}"; do
      for cut in $variants; do
        o="$out/$scene-$kind-s$seed-${cut/:/-}"
        args=()
        label="$cut"
        case "$cut" in
          storey) args=(--section-box "$box") label="box y ≤ $top m" ;;
          hide:*) args=(--hide "${cut#hide:}") label="${cut#hide:} hidden" ;;
          xray:*) args=(--xray "${cut#xray:}") label="${cut#xray:} x-rayed" ;;
          walk) args=(--walk) label="walked" ;;
        esac
        $B/hlod-bench "$dir/$scene.hlod" --path-kind "$kind" --seed "$seed" --frames "$frames" \
          --modes incore,pre --budget "$budget" --disk ssd "${args[@]}" --out "$o" > "$o.log" 2>&1
        read -r fm _ fx < <(stats "$o/pre.csv" front_bytes 1048576)
        read -r ft _ _ < <(stats "$o/pre.csv" front_tris 1)
        read -r im ip _ < <(stats "$o/incore.csv" frame_ms 1)
        read -r pm pp _ < <(stats "$o/pre.csv" frame_ms 1)
        read -r s2 _ < <(sum "$o/pre.csv" stage2_bytes 1048576)
        read -r _ subs < <(sum "$o/pre.csv" substituted 1)
        echo "| $scene | $kind | $seed | $label | $fm / $fx | ${ft%.*} | $im / $ip | $pm / $pp | $s2 | $subs |" >> "$summary"
        if [ "$cut" = walk ]; then
          echo "$scene $kind s$seed: $(grep '^walk:' "$o.log")" >> "$out/walk-lines.txt"
        fi
      done
    done
  done
done
cat "$summary"
