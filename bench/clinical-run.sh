#!/usr/bin/env bash
# Issue 22's GPU measurements, run by bench/gpu-run.sh (EXTRA=bench/clinical-run.sh)
# on the lent GPU machine: the reconstruction study, 720p frame times with
# tricubic on and off, a crop and labels, and the images of docs/rendering.md.
set -uo pipefail
cd "$(dirname "$0")/.."
out=${OUT:-gpu-out}
bin=/tmp/cv/bin data=/tmp/cv/data
export LD_LIBRARY_PATH=/tmp/cv/lib
mkdir -p "$out/images"
# Scene files name ../shared/data, as in a checkout beside the shared folder.
mkdir -p ../shared && ln -sfn "$data" ../shared/data && echo "data linked at ../shared/data"

"$bin/cinevol-bench" reconstruction --backend cuda --spacing 2 --spacing 3 --images "$out/images" \
  --out "$out/reconstruction.md" > "$out/reconstruction.log" 2>&1
echo "reconstruction rc=$?"
for scene in ct-head-cthead ct-head-cthead-half ct-chest-vessels ct-body ct-body-no-ribs; do
  "$bin/cinevol-bench" render --scene "bench/scenes/$scene.json" --backend cuda --frames 100 --warmup 10 \
    --out "$out/performance.md" > "$out/bench-$scene.log" 2>&1
  echo "bench $scene rc=$?"
done
for r in trilinear tricubic; do
  "$bin/cinevol" render --scene examples/ct-chest-vessels.json --backend cuda --spp 1024 --reconstruction $r \
    --out "$out/images/ct-chest-vessels-$r.png" 2>&1 | tail -1
done
for scene in ct-body-liver ct-body-no-ribs; do
  "$bin/cinevol" render --scene "examples/$scene.json" --backend cuda --spp 1024 --out "$out/images/$scene.png" 2>&1 | tail -1
done
cat "$out/reconstruction.md" 2>/dev/null
# One archive: the device tool returns a limited number of files.
tar czf "$out/clinical.tgz" -C "$out" images reconstruction.md reconstruction.log && rm -rf "$out/images"
