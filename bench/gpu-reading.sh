#!/usr/bin/env bash
# Slices and picks on the GPU machine's CPU (docs/performance.md, "Slices and
# picks"), after bench/gpu-run.sh has unpacked the bundle in /tmp/cv: a pick
# at the centre of CThead's 1280x720 view, and 512x512 axial slices of the
# 512^3 head phantom on 1 and on every core (thin, and a 20 mm maximum slab).
set -u
cd "$(dirname "$0")/.."
bin=/tmp/cv/bin data=/tmp/cv/data
export LD_LIBRARY_PATH=/tmp/cv/lib
sed "s|../../../shared/data/ct-head-cthead|$data/ct-head-cthead|" bench/scenes/ct-head-cthead.json > /tmp/cthead.json
echo '{"volume": {"phantom": {"kind": "HEAD", "size": 512}}}' > /tmp/head512.json
echo "$(nproc) cores"
for _ in 1 2 3; do "$bin/cinevol" pick --scene /tmp/cthead.json --x 640 --y 360; done
for threads in 1 "$(nproc)"; do
  for slab in 0 20; do
    for _ in 1 2 3; do
      CINEVOL_THREADS=$threads "$bin/cinevol" slice --scene /tmp/head512.json --slab "$slab" --out /tmp/s.png | \
        sed "s/^/threads $threads: /"
    done
  done
done
