#!/usr/bin/env bash
# Packs the built programs, their libraries and the data sets the GPU checks
# use into .gpu/bundle.tar.xz (kept out of git) for bench/gpu-run.sh.
# NO_DICOM=1 leaves the DICOM series out (the carry limit is 64 MiB with the
# working tree; only the reading and DICOM checks need it).
# PROGRAMS="cinevol-server ..." packs only those of build/ (the carry limit
# again: a run of tests and benches needs neither the client nor the viewer).
# All the programs with their libraries no longer fit one call (about 70 MiB
# packed): the script fails then, naming the sizes. A bench or two fit
# (PROGRAMS="cinevol-bench cinevol-reader"); the tests and the service with their libraries
# travel in bench/make-speed-bundle.sh's three folders.
# BEFORE=PATH packs an earlier build's cinevol-bench as cinevol-bench-before,
# for tables of before and after in one run (bench/gpu-run.sh).
set -euo pipefail
cd "$(dirname "$0")/.."
. bench/carry-limit.sh
stage=$(mktemp -d)
programs=${PROGRAMS:-cinevol cinevol-server cinevol-reader cinevol-bench cinevol-viewer tests/cinevol_tests}
# shellcheck disable=SC2086  # the programs are words
../shared/tools/device-bundle.sh "$stage" $(printf 'build/%s ' $programs)
if [ -n "${BEFORE:-}" ]; then
  cp -L "$BEFORE" "$stage/bin/cinevol-bench-before"
  strip --strip-unneeded "$stage/bin/cinevol-bench-before"
fi
mkdir -p "$stage/data"
cp -r ../shared/data/ct-head-cthead "$stage/data/"
cp ../shared/data/ct-body-totalsegmentator/aorta_ct_cropped.nii.gz "$stage/data/"
cp ../shared/data/mr-head-seg3d-nifti/MR.nii.gz "$stage/data/"
[ "${NO_DICOM:-0}" = 1 ] || cp -r ../shared/data/mr-chest-dicom-seg3d "$stage/data/"
# As under ../shared/data, for scene files that name it (bench/clinical-run.sh).
mkdir -p "$stage/data/ct-body-totalsegmentator"
cp ../shared/data/ct-body-totalsegmentator/{pulmonary_ct_cropped.nii.gz,example_ct.nii.gz,example_ct_sm.nii.gz,example_seg.nii.gz,labels-total.tsv} \
  "$stage/data/ct-body-totalsegmentator/"
chmod -R u+w "$stage"
mkdir -p .gpu
tar -I 'xz -T0 -9e' -cf .gpu/bundle.tar.xz -C "$stage" .
rm -rf "$stage"
du -h .gpu/bundle.tar.xz
check_carry .gpu/bundle.tar.xz
