#!/usr/bin/env bash
# Packs what bench/speed-run.sh runs on the GPU machine into OUT_DIR: this
# build's programs (bin/), an earlier build's server and bench (bin-before/,
# from BEFORE=folder holding cinevol-server and cinevol-bench), their
# libraries, CThead and its scene, as OUT_DIR/bundle.tar.xz, and the script
# as OUT_DIR/run.sh. Keep OUT_DIR out of git; carry it with the device call.
#   BEFORE=/path/to/old-build bench/make-speed-bundle.sh .gpu61
set -euo pipefail
cd "$(dirname "$0")/.."
dest=${1:?usage: bench/make-speed-bundle.sh OUT_DIR}
stage=$(mktemp -d)
../shared/tools/device-bundle.sh "$stage" build/cinevol-server build/cinevol build/cinevol-reader build/cinevol-bench \
  build/tests/cinevol_tests
if [ -n "${BEFORE:-}" ]; then
  before=$(mktemp -d)
  ../shared/tools/device-bundle.sh "$before" "$BEFORE/cinevol-server" "$BEFORE/cinevol-bench" build/cinevol-reader
  mv "$before/bin" "$stage/bin-before"
  cp -n "$before"/lib/* "$stage/lib/"
  rm -rf "$before"
fi
mkdir -p "$stage/data" "$stage/scenes"
cp -r ../shared/data/ct-head-cthead "$stage/data/"
cp bench/scenes/ct-head-cthead.json bench/scenes/stop-and-go.jsonl bench/scenes/tf-drag.jsonl "$stage/scenes/"
mkdir -p "$dest"
tar -I 'xz -T0 -6' -cf "$dest/bundle.tar.xz" -C "$stage" .
cp bench/speed-run.sh "$dest/run.sh"
rm -rf "$stage"
du -sh "$dest"/*
