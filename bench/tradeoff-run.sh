#!/usr/bin/env bash
# The speed/accuracy study on the GPU machine (docs/tradeoff.md), from the
# bundle of bench/make-gpu-bundle.sh. One run per dataset keeps each under the
# machine's per-command limit:
#   DATASET=ct-head-cthead bash bench/tradeoff-run.sh     # or mr-head, mr-head-256, phantom, ct-aorta
# EXTRA passes more flags to cinevol-bench tradeoff (e.g. "--variants-only");
# LIMIT (seconds) stops the study early and still packs its log.
# AB=1 runs the bundle's cinevol-bench-before (make-gpu-bundle.sh BEFORE=...)
# first, the references cached once, and prints bench/compare_tradeoff.py's
# table of the two: a before/after of one change, alternating by data set.
# Results (CSV, JSON, Markdown, half-size images) go to $OUT/tradeoff-$DATASET.tgz.
set -uo pipefail
cd "$(dirname "$0")/.."
out=${OUT:-gpu-out}
mkdir -p "$out" /tmp/cv
[ -x /tmp/cv/bin/cinevol-bench ] || tar xJf .gpu/bundle.tar.xz -C /tmp/cv
export LD_LIBRARY_PATH=/tmp/cv/lib
# The bench reads volumes through the reader cage: the reader travels with it.
for program in cinevol-bench cinevol-reader $([ "${AB:-0}" = 1 ] && echo cinevol-bench-before); do
  [ -x "/tmp/cv/bin/$program" ] || { echo "the bundle lacks $program (bench/make-gpu-bundle.sh PROGRAMS=, BEFORE=)"; exit 2; }
done
data=/tmp/cv/data
case "${DATASET:?set DATASET}" in
  ct-head-cthead) spec="ct-head-cthead=bench/scenes/ct-head-cthead.json,$data/ct-head-cthead/DERIVED_CThead.nhdr" ;;
  mr-head) spec="mr-head=examples/mr-head.json,$data/MR.nii.gz" ;;
  mr-head-256) # the shared T1 head on the reported head's grid (256x256x120, issue 38)
    [ -f /tmp/cv/mr-head-256.nrrd ] ||
      /tmp/cv/bin/cinevol-bench resample --volume "$data/MR.nii.gz" --size 256,256,120 --out /tmp/cv/mr-head-256.nrrd
    spec="mr-head-256=examples/mr-head.json,/tmp/cv/mr-head-256.nrrd" ;;
  phantom) spec="phantom=examples/ct-bone.json,phantom:head" ;;
  ct-aorta) spec="ct-aorta=bench/scenes/ct-aorta-bone.json,$data/aorta_ct_cropped.nii.gz" ;;
  *) echo "unknown DATASET $DATASET"; exit 2 ;;
esac
results=/tmp/cv/tradeoff-$DATASET
study() {  # PROGRAM RESULTS
  timeout "${LIMIT:-86400}" "$1" tradeoff --dataset "$spec" --backend cuda --width "${WIDTH:-1280}" --height "${HEIGHT:-720}" \
    --cache /tmp/cv/cache --out "$2" ${EXTRA:-} > "$2.log" 2>&1
  echo "tradeoff $DATASET $(basename "$1") rc=$?"
  cp "$2.log" "$2/"
}
if [ "${AB:-0}" = 1 ]; then
  study /tmp/cv/bin/cinevol-bench-before "$results-before"
  study /tmp/cv/bin/cinevol-bench "$results"
  tar czf "$out/tradeoff-$DATASET.tgz" -C /tmp/cv "tradeoff-$DATASET-before" "tradeoff-$DATASET"
  python3 bench/compare_tradeoff.py "$results-before/tradeoff.json" "$results/tradeoff.json"
  exit 0
fi
study /tmp/cv/bin/cinevol-bench "$results"
tar czf "$out/tradeoff-$DATASET.tgz" -C /tmp/cv "tradeoff-$DATASET"
grep -E "^[a-z-]+/|PSNR" "$results.log" | grep -E "/|none |svgf |wrls |knn |guided |accumulate " | head -60
