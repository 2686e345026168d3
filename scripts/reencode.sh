#!/usr/bin/env bash
# The re-encoding corpus on every test model: gltfpack (default, -cc) and
# gltf-transform (quantize, meshopt, instance, draco, weld, flatten) write each
# model again, and each file must import with the triangle count it declares
# and the plain model's box. Prints the table. The test suite runs the same
# test on the small models.
#
#   bash scripts/reencode.sh
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
HLOD_REENCODE_MODELS=all cargo test --release -p e2e-tests --test e2e -- \
  reencode::re_encodings --nocapture 2>&1 | grep -E '^\||test result|panicked'
