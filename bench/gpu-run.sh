#!/usr/bin/env bash
# Runs the GPU checks and benchmarks on the lent GPU machine from a bundle
# made by bench/make-gpu-bundle.sh (see docs/performance.md). Writes logs and
# tables to $OUT (or ./gpu-out) and prints a short summary last.
set -uo pipefail
cd "$(dirname "$0")/.."
out=${OUT:-gpu-out}
mkdir -p "$out" /tmp/cv
tar xJf .gpu/bundle.tar.xz -C /tmp/cv
export LD_LIBRARY_PATH=/tmp/cv/lib
bin=/tmp/cv/bin data=/tmp/cv/data
# The service tests start the bundle's programs, not the build tree's.
export CINEVOL_SERVER=$bin/cinevol-server CINEVOL_CLI=$bin/cinevol
nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv,noheader | tee "$out/gpu.txt"

# A bundle of benches alone (PROGRAMS=, the carry limit) holds no tests:
# bench/make-speed-bundle.sh carries them.
if [ ! -x "$bin/cinevol_tests" ]; then
  echo "tests: not in this bundle"
else
  "$bin/cinevol_tests" --gtest_filter="${TESTS:-*Cuda*}" > "$out/gpu-tests.log" 2>&1
  echo "tests rc=$?: $(grep -E '^\[  (PASSED|FAILED) ' "$out/gpu-tests.log" | tr '\n' ' ')"
fi

if [ "${SANITIZE:-1}" = 1 ] && [ -x "$bin/cinevol_tests" ]; then
  compute-sanitizer --tool memcheck --error-exitcode 9 "$bin/cinevol_tests" \
    --gtest_filter='CudaRenderer.FirstHits*:CudaRenderer.SameSeed*:*CudaDenoiser*wrls' > "$out/memcheck.log" 2>&1
  echo "memcheck rc=$?: $(grep -E 'ERROR SUMMARY' "$out/memcheck.log" | head -1)"
fi

# bench LABEL SUBCOMMAND SCENE:VOLUME [FLAGS...]: this build's bench, then the
# earlier build's where one was packed with BEFORE= (its tables apart).
bench() {
  local label=$1 command=$2 scene=$3
  shift 3
  "$bin/cinevol-bench" "$command" --scene "bench/scenes/${scene%%:*}.json" --volume "$data/${scene#*:}" \
    --backend cuda "$@" --out "$out/performance.md" > "$out/$label-${scene%%:*}.log" 2>&1
  echo "$label ${scene%%:*} rc=$?"
  [ -x "$bin/cinevol-bench-before" ] || return 0
  "$bin/cinevol-bench-before" "$command" --scene "bench/scenes/${scene%%:*}.json" --volume "$data/${scene#*:}" \
    --backend cuda "$@" --out "$out/performance-before.md" > "$out/$label-before-${scene%%:*}.log" 2>&1
  echo "$label before ${scene%%:*} rc=$?"
}
both="ct-head-cthead:ct-head-cthead/DERIVED_CThead.nhdr ct-aorta-bone:aorta_ct_cropped.nii.gz"
for scene in ${BENCH_SCENES:-$both}; do bench bench render "$scene" --frames 100 --warmup 10; done
for scene in ${DENOISE_SCENES:-$both}; do bench denoise denoise "$scene"; done
# Each JPEG encoder on the same frames (JPEG_ENCODER=auto notes nvJPEG's absence instead of failing).
for scene in ${ENCODE_SCENES:-ct-head-cthead:ct-head-cthead/DERIVED_CThead.nhdr}; do
  "$bin/cinevol-bench" encode --scene "bench/scenes/${scene%%:*}.json" --volume "$data/${scene#*:}" \
    --backend cuda --jpeg-encoder "${JPEG_ENCODER:-nvjpeg}" --frames 100 --warmup 10 \
    --out "$out/performance.md" > "$out/encode-${scene%%:*}.log" 2>&1
  echo "encode bench ${scene%%:*} rc=$?"
done
${EXTRA:-true}
cat "$out/performance-before.md" "$out/performance.md" 2>/dev/null
