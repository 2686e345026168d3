#!/usr/bin/env bash
# Serves the web viewer (viewer/web) with a 3D Tiles export, over HTTP on
# 127.0.0.1:PORT, with nginx (scripts/serve.sh):
#
#   hlod-build export-3dtiles scene.hlod -o DIR
#   bash scripts/serve-web.sh DIR [PORT]     (default port 8080; Ctrl-C stops it)
#
# then open http://127.0.0.1:PORT/ (URL parameters: see viewer/web/main.js).
# The page's libraries (three.js, 3DTilesRendererJS) are the ones
# scripts/setup.sh installs in target/web; the site is a temporary folder of
# links to the page, those libraries and DIR (as tiles/).
set -euo pipefail
if [ $# -lt 1 ] || [ ! -f "$1/tileset.json" ]; then
  echo "usage: serve-web.sh DIR [PORT]  (DIR: a folder written by hlod-build export-3dtiles)" >&2
  exit 2
fi
repo=$(cd "$(dirname "$0")/.." && pwd)
tiles=$(cd "$1" && pwd)
modules="$repo/target/web/node_modules"
[ -d "$modules/3d-tiles-renderer" ] || { echo "serve-web.sh: $modules has no 3d-tiles-renderer (run scripts/setup.sh)" >&2; exit 1; }
# Under SERVE_TMP when given (the tests' log folder, removed with it).
base=${SERVE_TMP:-${TMPDIR:-/tmp}}
mkdir -p "$base"
site=$(mktemp -d "$base/site.XXXXXX")
trap 'rm -rf "$site"' EXIT
ln -s "$repo/viewer/web/index.html" "$repo/viewer/web/main.js" "$site/"
ln -s "$modules" "$site/node_modules"
ln -s "$tiles" "$site/tiles"
# nginx runs as this shell's child: a TERM or INT to the shell stops it too
# (a caller that kills this script alone, as bench-3dtiles.sh does, left it
# running), and the EXIT trap removes the site.
bash "$repo/scripts/serve.sh" "$site" "${2:-8080}" &
server=$!
trap 'kill "$server" 2>/dev/null; wait "$server" 2>/dev/null; exit 143' TERM INT
wait "$server"
