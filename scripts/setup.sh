#!/usr/bin/env bash
# One-time machine set-up for a fresh Debian with only Rust: installs the system
# packages the build needs. Idempotent; does nothing when all are present.
set -euo pipefail

need=()
command -v c++ >/dev/null 2>&1 || need+=(g++)          # meshopt's vendored C++
command -v cc >/dev/null 2>&1 || need+=(gcc)
command -v pkg-config >/dev/null 2>&1 || need+=(pkg-config)
# The reference Draco decoder (KHR_draco_mesh_compression), linked by the builder.
has_pkg() { dpkg-query -W -f='${Status}' "$1" 2>/dev/null | grep -q "install ok installed"; }
has_pkg libdraco-dev || need+=(libdraco-dev)
# Software Vulkan (lavapipe) so that the wgpu renderer runs without a GPU.
has_pkg mesa-vulkan-drivers || need+=(mesa-vulkan-drivers)
has_pkg libvulkan1 || need+=(libvulkan1)
# Python for IfcOpenShell (IFC input), in a virtual environment below.
command -v python3 >/dev/null 2>&1 || need+=(python3)
python3 -c "import venv, ensurepip" >/dev/null 2>&1 || need+=(python3-venv)
# Node and npm for gltfpack and gltf-transform (the re-encoding corpus test).
command -v node >/dev/null 2>&1 || need+=(nodejs)
command -v npm >/dev/null 2>&1 || need+=(npm)
# Headless Chromium for the web viewer's browser test (3D Tiles export).
has_pkg chromium || need+=(chromium)
# A virtual display for the viewer's window test.
command -v xvfb-run >/dev/null 2>&1 || need+=(xvfb)
command -v xauth >/dev/null 2>&1 || need+=(xauth)
# A single-node Slurm cluster with job accounting, started by the cluster-build
# test (scripts/slurm-local.sh): Slurm, munge, slurmdbd and MariaDB for it.
# nginx for scenes served over HTTP (scripts/serve.sh and the remote tests).
for p in slurm-wlm slurm-client munge slurmdbd mariadb-server nginx-light; do
  has_pkg "$p" || need+=("$p")
done

if [ ${#need[@]} -gt 0 ]; then
  echo "setup: installing ${need[*]}"
  SUDO=""
  if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
  export DEBIAN_FRONTEND=noninteractive
  $SUDO apt-get update -qq
  $SUDO apt-get install -y -qq --no-install-recommends "${need[@]}"
fi
command -v cargo >/dev/null 2>&1 || { echo "setup: cargo not found; install Rust first" >&2; exit 1; }

# IfcOpenShell, which reads IFC files for `hlod-build` and `hlod-view`: in
# target/ifc-venv, where they look for it (HLOD_PYTHON overrides). Pinned, so
# that an IFC file converts to the same scene everywhere.
IFCOPENSHELL=0.9.0.post1
venv="$(cd "$(dirname "$0")/.." && pwd)/target/ifc-venv"
if ! "$venv/bin/python" -c "import ifcopenshell, sys; sys.exit(ifcopenshell.version != '$IFCOPENSHELL')" >/dev/null 2>&1; then
  echo "setup: installing IfcOpenShell $IFCOPENSHELL in target/ifc-venv"
  rm -rf "$venv"
  python3 -m venv "$venv"
  "$venv/bin/python" -m pip install -q --disable-pip-version-check "ifcopenshell==$IFCOPENSHELL"
fi

# gltfpack and gltf-transform, which write the re-encoding corpus
# (tests/tests/e2e/reencode.rs, scripts/reencode.sh): in target/npm-tools, pinned.
tools="$(cd "$(dirname "$0")/.." && pwd)/target/npm-tools"
if ! [ -x "$tools/node_modules/.bin/gltfpack" ] || ! [ -x "$tools/node_modules/.bin/gltf-transform" ] ||
  ! grep -q '"version": "4.5.1"' "$tools/node_modules/@gltf-transform/cli/package.json" 2>/dev/null; then
  echo "setup: installing gltfpack 1.3.0 and gltf-transform 4.5.1 in target/npm-tools"
  mkdir -p "$tools"
  npm install --silent --no-audit --no-fund --prefix "$tools" gltfpack@1.3.0 @gltf-transform/cli@4.5.1
fi

# An S3-compatible object store for the publishing test (hlod-builder/tests/publish.rs)
# and boto3 to check it with an independent client: moto's server in
# target/moto-venv, pinned.
MOTO=5.2.6
moto="$(cd "$(dirname "$0")/.." && pwd)/target/moto-venv"
if ! "$moto/bin/python" -c "import moto, boto3, sys; sys.exit(moto.__version__ != '$MOTO')" >/dev/null 2>&1 ||
  ! [ -x "$moto/bin/moto_server" ]; then
  echo "setup: installing moto[server] $MOTO in target/moto-venv"
  rm -rf "$moto"
  python3 -m venv "$moto"
  "$moto/bin/python" -m pip install -q --disable-pip-version-check "moto[server]==$MOTO"
fi

# The web viewer's libraries (three.js, 3DTilesRendererJS) and playwright-core,
# which drives Chromium in the browser test: in target/web, as pinned by
# viewer/web/package-lock.json.
web="$(cd "$(dirname "$0")/.." && pwd)/target/web"
lock="$(cd "$(dirname "$0")/.." && pwd)/viewer/web/package-lock.json"
if ! cmp -s "$lock" "$web/package-lock.json" || ! [ -d "$web/node_modules/3d-tiles-renderer" ]; then
  echo "setup: installing the web viewer's libraries in target/web"
  rm -rf "$web"
  mkdir -p "$web"
  cp "$(dirname "$lock")/package.json" "$lock" "$web/"
  (cd "$web" && npm ci --silent --no-audit --no-fund)
fi

# The official 3D Tiles validator (CesiumGS' 3d-tiles-validator 0.6.1) for the
# export test: not on the npm registry, so it is installed from the prebuilt
# copy beside the project (../shared/tools, or HLOD_3DTILES_VALIDATOR_SRC), its
# dependencies from the registry, in target/3d-tiles-validator.
val="$(cd "$(dirname "$0")/.." && pwd)/target/3d-tiles-validator"
src=${HLOD_3DTILES_VALIDATOR_SRC:-$(cd "$(dirname "$0")/.." && pwd)/../shared/tools/3d-tiles-validator}
if ! [ -f "$val/build/main.js" ] || ! [ -d "$val/node_modules/3d-tiles-tools" ]; then
  if [ -f "$src/package.json" ]; then
    echo "setup: installing the 3D Tiles validator in target/3d-tiles-validator"
    rm -rf "$val"
    cp -r "$src" "$val"
    (cd "$val" && npm ci --omit=dev --silent --no-audit --no-fund)
  else
    echo "setup: no 3D Tiles validator at $src: the export test will be skipped (set HLOD_3DTILES_VALIDATOR_SRC)"
  fi
fi
