#!/usr/bin/env bash
# README command 2: install, build, then run the whole test suite, and in CI
# the short fuzz runs. Ends with ctest's summary line (repeated after its list
# of skipped tests and the fuzz summary).
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/install-deps.sh
# Every target, CUDA included wherever nvcc is (GPU or not): CUDA code must
# keep compiling. A build/ the demo configured without CUDA is configured
# again; CINEVOL_CUDA=OFF keeps it without.
CINEVOL_CUDA="${CINEVOL_CUDA:-AUTO}" scripts/build.sh
cd build
log=$(mktemp)
status=0
ctest --output-on-failure -j "$(nproc)" "$@" 2>&1 | tee "$log" || status=$?
cd ..
# Short libFuzzer runs (tests/fuzz/run.sh: a clang build in build-fuzz/, then
# a fixed replay of about 20 s per target; about 5 minutes on 2 cores) in CI,
# or locally with FUZZ=1;
# FUZZ=0 skips them. Their summary comes before ctest's line, which stays last.
if [ "${FUZZ:-${CI:-false}}" = "1" ] || [ "${FUZZ:-${CI:-false}}" = "true" ]; then
  echo "---- fuzzing (tests/fuzz/run.sh ${FUZZ_SECONDS:-60}: a replay of seed 1, a fixed count per target)"
  tests/fuzz/run.sh "${FUZZ_SECONDS:-60}" 2>&1 || { [ "$status" -ne 0 ] || status=1; }
fi
grep -E "tests passed|tests failed" "$log" | tail -1
rm -f "$log"
exit "$status"
