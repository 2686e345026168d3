#!/usr/bin/env bash
# One-time machine set-up for a fresh Debian with only Rust: installs the system
# packages the build needs. Idempotent; does nothing when all are present.
set -euo pipefail

need=()
command -v c++ >/dev/null 2>&1 || need+=(g++)          # meshopt's vendored C++
command -v cc >/dev/null 2>&1 || need+=(gcc)
command -v pkg-config >/dev/null 2>&1 || need+=(pkg-config)
# Software Vulkan (lavapipe) so that the wgpu renderer runs without a GPU.
has_pkg() { dpkg-query -W -f='${Status}' "$1" 2>/dev/null | grep -q "install ok installed"; }
has_pkg mesa-vulkan-drivers || need+=(mesa-vulkan-drivers)
has_pkg libvulkan1 || need+=(libvulkan1)
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
