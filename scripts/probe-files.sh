#!/usr/bin/env bash
# The file-handling probes of docs/results.md ("Every file a command
# touches"), on the release binaries: exit status, wall time and peak RSS
# (GNU time, Debian's `time`) and the last line of stderr of each. Needs
# `cargo build --release` first, and xvfb-run for the viewer's lines.
#
#   bash scripts/probe-files.sh
set -u
cd "$(dirname "$0")/.."
R=$PWD/target/release
DATA=$PWD/tests/data
D=$(mktemp -d); cd "$D"
t() { /usr/bin/time -f "%e s, %M KB" -o time.txt timeout 120 "$@" > out.txt 2> err.txt; echo "exit $? | $(tail -1 time.txt) | $(grep -v '^\s*$' err.txt | tail -1 | cut -c1-200)"; }
$R/hlod-build gen plant --objects 12 --triangles 6000 -o m.gltf > /dev/null
cp m.bin m.bin.orig
echo "## outputs onto inputs"
echo "build m.gltf -o m.bin: $(t $R/hlod-build build m.gltf -o m.bin -q)"; cmp -s m.bin m.bin.orig && echo "  m.bin unchanged"
echo "gen tile m.gltf -o m.bin: $(t $R/hlod-build gen tile m.gltf --grid 2x2 -o m.bin)"; cmp -s m.bin m.bin.orig && echo "  m.bin unchanged"
$R/hlod-build build m.gltf -o s.hlod -q; cp s.hlod s.orig
for f in --csv --screenshot --record; do echo "hlod-view s.hlod $f s.hlod: $(t env -u DISPLAY $R/hlod-view s.hlod $f s.hlod)"; done; cmp -s s.hlod s.orig && echo "  s.hlod unchanged"
echo "hlod-view s.hlod --screenshot /dev/null: $(t env -u DISPLAY $R/hlod-view s.hlod --screenshot /dev/null)"
mkdir o; cp s.hlod o/summary.md
echo "hlod-bench o/summary.md --out o: $(t $R/hlod-bench o/summary.md --frames 10 --fps 0 --out o)"; cmp -s o/summary.md s.orig && echo "  o/summary.md unchanged"
echo "## FIFOs"
mkfifo pipe
for c in "info pipe" "build pipe -o x.hlod" "mt pipe" "vdt pipe" "gen tile pipe --grid 2x2 -o x.glb" "relayout pipe -o x.hlod"; do echo "hlod-build $c: $(t $R/hlod-build $c)"; done
echo "hlod-bench pipe: $(t $R/hlod-bench pipe --frames 10 --out o2)"
echo "hlod-bench s.hlod --path pipe: $(t $R/hlod-bench s.hlod --path pipe --frames 10 --out o2)"
echo "mt-bench pipe: $(t $R/mt-bench pipe --out o2)"
echo "vdt-bench pipe: $(t $R/vdt-bench pipe --out o2)"
echo "hlod-view pipe --exit-when-complete: $(t xvfb-run -a $R/hlod-view pipe --exit-when-complete)"
echo "hlod-view s.hlod --path pipe: $(t env -u DISPLAY $R/hlod-view s.hlod --path pipe)"
sed 's/"uri":"m.bin"/"uri":"pipe"/' m.gltf > piped.gltf
echo "build piped.gltf (buffer uri a FIFO): $(t $R/hlod-build build piped.gltf -o x.hlod)"
echo "## uris"
mkdir -p sub/model; cp m.gltf sub/model/; mv m.bin sub/secret.bin
sed 's/"uri":"m.bin"/"uri":"..\/secret.bin"/' sub/model/m.gltf > sub/model/up.gltf
sed 's/"uri":"m.bin"/"uri":"%2e%2e\/secret.bin"/' sub/model/m.gltf > sub/model/pct.gltf
echo "build ../secret.bin uri: $(t $R/hlod-build build sub/model/up.gltf -o x.hlod)"
echo "build %2e%2e uri: $(t $R/hlod-build build sub/model/pct.gltf -o x.hlod)"
echo "build ../secret.bin uri --allow-dir sub: $(t $R/hlod-build build sub/model/up.gltf -o x.hlod -q --allow-dir sub)"
mv sub/secret.bin m.bin
echo "## memory before refusal: m.bin made a 10 GB sparse file"
truncate -s 10G m.bin
echo "mt m.gltf: $(t $R/hlod-build mt m.gltf)"
echo "gen tile m.gltf: $(t $R/hlod-build gen tile m.gltf --grid 2x2 -o t.glb)"
echo "build m.gltf: $(t $R/hlod-build build m.gltf -o b.hlod -q)"
python3 - <<'PY'
import json
j=json.load(open('m.gltf'))
nodes=[{"mesh":0},{"mesh":0}]
for k in range(1,60):
    below=[2*(k-1),2*(k-1)+1]
    nodes+= [{"children":below},{"children":below}]
j["nodes"]=nodes; j["scenes"]=[{"nodes":[118,119]}]; j["scene"]=0
json.dump(j,open('dag.gltf','w'))
PY
echo "build dag.gltf (2^60 placements): $(t $R/hlod-build build dag.gltf -o dag.hlod)"
echo "## one-node scene"
$R/hlod-build build $DATA/dragon_res4.glb -o d.hlod -q
$R/hlod-bench d.hlod --occlusion 0.1 --budget 100% --frames 30 --out od 2>&1 | grep "^| \(mode\|nopre\|pre\)"
$R/hlod-bench d.hlod --budget 100KiB --frames 30 --out od 2>&1 | grep "WARN" | head -1 | cut -c1-160
echo "hlod-view d.hlod --budget 100KiB --exit-when-complete: $(t xvfb-run -a $R/hlod-view d.hlod --budget 100KiB --exit-when-complete)"
echo "hlod-view d.hlod --exit-when-complete (auto): $(t xvfb-run -a $R/hlod-view d.hlod --exit-when-complete)"
printf '%s' '{"asset":{"version":"2.0"},"scene":0,"scenes":[{"nodes":[0]}],"nodes":[{"mesh":0}],"meshes":[{"primitives":[{"attributes":{"POSITION":0}}]}],"accessors":[{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3","min":[0,0,0],"max":[1,1,0]}],"bufferViews":[{"buffer":0,"byteLength":36}],"buffers":[{"byteLength":36,"uri":"data:application/octet-stream;base64,AAAAAAAAAAAAAAAAAACAPwAAAAAAAAAAAAAAAAAAgD8AAAAA"}]}' > tri.gltf
$R/hlod-build build tri.gltf -o tri.hlod -q
echo "hlod-view tri.hlod --budget auto --exit-when-complete: $(t xvfb-run -a $R/hlod-view tri.hlod --exit-when-complete)"
echo "## leftovers"
cp $DATA/bunny.glb b.glb
$R/hlod-build build b.glb -o k.hlod -q --vdt-tris 2000 & P=$!; while ! ls -a | grep -q hlod-tmp; do sleep 0.01; done; kill -KILL $P; wait $P 2>/dev/null
echo "left after SIGKILL: $(ls -a | grep -c hlod-tmp)"
echo "next build: $(t $R/hlod-build build tri.gltf -o k2.hlod -q); said: $(grep -c 'interrupted run' err.txt); left: $(ls -a | grep -c hlod-tmp)"
rm -rf "$D"
