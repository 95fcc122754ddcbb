#!/usr/bin/env bash
# README command 1: install, build what the demo runs (cinevol-server,
# cinevol and cinevol-reader, which the server reads files through), then
# run `cinevol demo` (on the shared data's CT beside the checkout, else the built-in phantom). CUDA is built only where nvcc
# can build for a GPU this machine has, or with CINEVOL_CUDA=ON
# (scripts/build.sh). Everything else (tests, benches, the viewer) is
# scripts/test.sh's, or `scripts/build.sh` with no arguments.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/install-deps.sh
CINEVOL_CUDA_DEFAULT=GPU scripts/build.sh cinevol-server cinevol cinevol-reader
exec "${CINEVOL_BUILD_DIR:-build}/cinevol" demo "$@"
