#!/usr/bin/env bash
# Configures (once) and builds cinevol into build/. CUDA is used when nvcc is
# found; set CINEVOL_CUDA=OFF to build for the CPU only.
set -euo pipefail
cd "$(dirname "$0")/.."
if [ ! -f build/build.ninja ]; then
  cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release \
    -DCINEVOL_CUDA="${CINEVOL_CUDA:-AUTO}"
fi
cmake --build build -j "$(nproc)"
