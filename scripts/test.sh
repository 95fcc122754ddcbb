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
echo "---- install and build: $SECONDS s"

# Short libFuzzer runs (tests/fuzz/run.sh: a clang build in build-fuzz/, then
# a fixed replay of about 20 s per target, two at a time) in CI, or locally
# with FUZZ=1; FUZZ=0 skips them. Their build runs beside ctest at the lowest
# priority: it takes the core that the serial tests (the browser's, the
# frame-rate ones) leave idle, and yields the other to the tests.
fuzzing=false
case "${FUZZ:-${CI:-false}}" in 1 | true) fuzzing=true ;; esac
if $fuzzing; then
  fuzz_build_log=$(mktemp)
  # Its last line says when it ended, for the summary below.
  nice -n 19 bash -c 'tests/fuzz/run.sh --build-only; rc=$?; echo "ended $SECONDS s in"; exit $rc' \
    >"$fuzz_build_log" 2>&1 &
  fuzz_build=$!
fi
ctest_start=$SECONDS

cd build
log=$(mktemp)
status=0
ctest --output-on-failure -j "$(nproc)" "$@" 2>&1 | tee "$log" || status=$?
cd ..
echo "---- ctest: $((SECONDS - ctest_start)) s"
# The fuzz summary comes before ctest's line, which stays last.
if $fuzzing; then
  echo "---- fuzzing (tests/fuzz/run.sh ${FUZZ_SECONDS:-60}: a replay of seed 1, a fixed count per target)"
  if wait "$fuzz_build"; then
    echo "fuzz: the build $(tail -n 1 "$fuzz_build_log") of ctest's $((SECONDS - ctest_start))"
    fuzz_start=$SECONDS
    FUZZ_JOBS="${FUZZ_JOBS:-$(nproc)}" tests/fuzz/run.sh "${FUZZ_SECONDS:-60}" 2>&1 || { [ "$status" -ne 0 ] || status=1; }
    echo "fuzz: the runs took $((SECONDS - fuzz_start)) s"
  else
    echo "fuzz: the build failed:"
    tail -n 60 "$fuzz_build_log"
    [ "$status" -ne 0 ] || status=1
  fi
  rm -f "$fuzz_build_log"
fi
grep -E "tests passed|tests failed" "$log" | tail -1
rm -f "$log"
exit "$status"
