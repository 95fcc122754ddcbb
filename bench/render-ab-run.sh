#!/usr/bin/env bash
# A change to the path tracer, before and after in one call on the GPU machine,
# from the bundle of bench/make-gpu-bundle.sh with
# PROGRAMS="cinevol-bench cinevol-reader" NO_DICOM=1 BEFORE=<the earlier cinevol-bench>:
#   - cinevol-bench render's default configuration at 1280x720, ms a frame, on
#     CThead, the MR head, the aorta crop and the phantom, the builds alternating,
#     ROUNDS (2) times;
#   - both builds' trade-off study of CThead at 640x360 (orbit and point light,
#     the denoisers), compared by bench/compare_tradeoff.py: a quick look at the
#     images. The study's 28 runs at 720p, one data set a call:
#     DATASET=... AB=1 EXTRA="--frames-scale 0.5 --reference-spp 256
#     --reference-bounces 4 --variants-only" bash bench/tradeoff-run.sh
set -uo pipefail
cd "$(dirname "$0")/.." || exit 2
out=${OUT:-gpu-out}
mkdir -p "$out" /tmp/cv
[ -x /tmp/cv/bin/cinevol-bench-before ] || tar xJf .gpu/bundle.tar.xz -C /tmp/cv
export LD_LIBRARY_PATH=/tmp/cv/lib
bin=/tmp/cv/bin data=/tmp/cv/data
for program in cinevol-bench cinevol-bench-before cinevol-reader; do
  [ -x "$bin/$program" ] || { echo "the bundle lacks $program (bench/make-gpu-bundle.sh PROGRAMS=, BEFORE=)"; exit 2; }
done
nvidia-smi --query-gpu=name --format=csv,noheader
cthead="bench/scenes/ct-head-cthead.json:$data/ct-head-cthead/DERIVED_CThead.nhdr"
scenes=("$cthead" "examples/mr-head.json:$data/MR.nii.gz"
  "bench/scenes/ct-aorta-bone.json:$data/aorta_ct_cropped.nii.gz" "examples/ct-bone.json:phantom:head")
for round in $(seq "${ROUNDS:-2}"); do
  for scene in "${scenes[@]}"; do
    for build in cinevol-bench-before cinevol-bench; do
      ms=$("$bin/$build" render --scene "${scene%%:*}" --volume "${scene#*:}" --backend cuda --width 1280 \
        --height 720 --frames 40 --warmup 5 --default-only 2> /dev/null | grep '^| default' | awk -F'|' '{print $4}')
      echo "render $(basename "${scene%%:*}" .json), $build, round $round: ${ms:-failed} ms"
    done
  done
done
for build in cinevol-bench-before cinevol-bench; do
  rm -rf "/tmp/cv/study-$build"
  "$bin/$build" tradeoff --dataset "ct=${cthead%%:*},${cthead#*:}" --width 640 --height 360 --reference-spp 64 \
    --frames-scale 0.3 --scenario orbit --scenario point-light --denoisers-only --backend cuda \
    --cache /tmp/cv/study-cache --out "/tmp/cv/study-$build" > "$out/study-$build.log" 2>&1
  echo "study $build rc=$?"
done
python3 bench/compare_tradeoff.py /tmp/cv/study-cinevol-bench-before/tradeoff.json /tmp/cv/study-cinevol-bench/tradeoff.json
