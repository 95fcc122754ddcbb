#!/usr/bin/env bash
# README command 2: install, build, then run the whole test suite. Ends with
# ctest's summary line (repeated after its list of skipped tests).
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/install-deps.sh
scripts/build.sh
cd build
log=$(mktemp)
status=0
ctest --output-on-failure -j "$(nproc)" "$@" 2>&1 | tee "$log" || status=$?
grep -E "tests passed|tests failed" "$log" | tail -1
rm -f "$log"
exit "$status"
