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
# A virtual display for the viewer's window test.
command -v xvfb-run >/dev/null 2>&1 || need+=(xvfb)
command -v xauth >/dev/null 2>&1 || need+=(xauth)

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
