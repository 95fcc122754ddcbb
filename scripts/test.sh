#!/usr/bin/env bash
# README command 2: install, build, then run the whole test suite.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/install-deps.sh
scripts/build.sh
cd build
exec ctest --output-on-failure -j "$(nproc)" "$@"
