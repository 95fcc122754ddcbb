#!/usr/bin/env bash
# Still frames after an orbit (docs/tradeoff.md, "Still frames"): `cinevol-bench
# refine` on CThead, the MR head and the head phantom, on the GPU machine from
# the bundle of bench/make-gpu-bundle.sh, at 1280x720 against 4096 spp.
#   WIDTH=1280 HEIGHT=720 REFERENCE_SPP=4096 TARGET_SPP=512 bash bench/refine-run.sh
# With BACKEND=cpu and a small size it runs here from the build tree
# (BIN=build DATA=../shared/data).
set -uo pipefail
cd "$(dirname "$0")/.."
out=${OUT:-gpu-out}
mkdir -p "$out"
if [ -z "${BIN:-}" ]; then
  [ -x /tmp/cv/bin/cinevol-bench ] || { mkdir -p /tmp/cv && tar xJf .gpu/bundle.tar.xz -C /tmp/cv; }
  export LD_LIBRARY_PATH=/tmp/cv/lib
fi
bin=${BIN:-/tmp/cv/bin} data=${DATA:-/tmp/cv/data}
mr=$data/MR.nii.gz
[ -f "$mr" ] || mr=$data/mr-head-seg3d-nifti/MR.nii.gz
for run in "bench/scenes/ct-head-cthead.json:$data/ct-head-cthead/DERIVED_CThead.nhdr" \
           "examples/mr-head.json:$mr" "examples/ct-bone.json:phantom:head"; do
  "$bin/cinevol-bench" refine --scene "${run%%:*}" --volume "${run#*:}" --backend "${BACKEND:-cuda}" \
    --width "${WIDTH:-1280}" --height "${HEIGHT:-720}" --reference-spp "${REFERENCE_SPP:-4096}" \
    --target-spp "${TARGET_SPP:-512}" --out "$out/refine.md" --csv "$out/refine.csv" > "$out/refine-$(basename "${run%%:*}" .json).log" 2>&1
  echo "refine ${run%%:*} rc=$?"
done
cat "$out/refine.md"
