#!/usr/bin/env bash
# Packs what bench/speed-run.sh runs on the GPU machine into OUT_DIR, in
# three folders, each under the device tool's 64 MiB carry:
#   OUT_DIR/libs-a, OUT_DIR/libs-b  the programs' shared libraries, in halves
#   OUT_DIR/programs                this build's programs (bin/), an earlier build's
#                                   (bin-before/, from BEFORE=folder holding its
#                                   cinevol-server, cinevol-bench and, if there,
#                                   cinevol_tests), CThead and its scenes, and
#                                   speed-run.sh as run.sh
# Keep OUT_DIR out of git (.gpu/ is ignored). On the GPU machine, three calls
# while it stays warm, each carrying one folder:
#   mkdir -p .gpu/cv/lib && tar xJf OUT_DIR/libs-a/libs.tar.xz -C .gpu/cv/lib
#   tar xJf OUT_DIR/libs-b/libs.tar.xz -C .gpu/cv/lib
#   CV=$PWD/.gpu/cv BUNDLE=OUT_DIR/programs OUT=$OUT STEPS=... bash OUT_DIR/programs/run.sh
#
#   BEFORE=/path/to/old-build bench/make-speed-bundle.sh .gpu/speed
set -euo pipefail
cd "$(dirname "$0")/.."
. bench/carry-limit.sh
dest=${1:?usage: bench/make-speed-bundle.sh OUT_DIR}
stage=$(mktemp -d)
../shared/tools/device-bundle.sh "$stage" build/cinevol-server build/cinevol build/cinevol-reader build/cinevol-bench \
  build/tests/cinevol_tests
if [ -n "${BEFORE:-}" ]; then
  before=$(mktemp -d) programs=("$BEFORE/cinevol-server" "$BEFORE/cinevol-bench" build/cinevol-reader)
  [ -x "$BEFORE/cinevol_tests" ] && programs+=("$BEFORE/cinevol_tests")
  ../shared/tools/device-bundle.sh "$before" "${programs[@]}"
  mv "$before/bin" "$stage/bin-before"
  cp -n "$before"/lib/* "$stage/lib/"
  rm -rf "$before"
fi
mkdir -p "$stage/data" "$stage/scenes"
cp -r ../shared/data/ct-head-cthead "$stage/data/"
cp bench/scenes/ct-head-cthead.json bench/scenes/stop-and-go.jsonl bench/scenes/tf-drag.jsonl "$stage/scenes/"
rm -rf "$dest/libs-a" "$dest/libs-b" "$dest/programs"
mkdir -p "$dest/libs-a" "$dest/libs-b" "$dest/programs"
# The libraries in two halves by name: each about 30 MiB packed.
mapfile -t libs < <(ls "$stage/lib")
half=$(( (${#libs[@]} + 1) / 2 ))
tar -I 'xz -T0 -9' -cf "$dest/libs-a/libs.tar.xz" -C "$stage/lib" "${libs[@]:0:half}"
tar -I 'xz -T0 -9' -cf "$dest/libs-b/libs.tar.xz" -C "$stage/lib" "${libs[@]:half}"
rm -rf "$stage/lib"
tar -I 'xz -T0 -9' -cf "$dest/programs/bundle.tar.xz" -C "$stage" .
cp bench/speed-run.sh "$dest/programs/run.sh"
rm -rf "$stage"
du -sh "$dest"/*
for folder in "$dest"/*; do check_carry "$folder"; done
