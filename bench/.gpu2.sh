set -u
rm -rf /tmp/cv; mkdir -p /tmp/cv; tar xJf .gpu/bundle.tar.xz -C /tmp/cv; export LD_LIBRARY_PATH=/tmp/cv/lib
nvidia-smi --query-gpu=name --format=csv,noheader
V="--variant before:stabilize_still=0,hold=0 --variant svgf-plain:method=svgf,hold=0 --variant hold-only:stabilize_still=0 --variant recentred:still_recenter=1 --variant still8:stabilize_still=8"
for d in ${DATASETS:-mr-head ct-head-cthead phantom ct-aorta}; do
  ( OUT=/tmp/o-$d DATASET=$d LIMIT=${LIMIT:-540} EXTRA="--frames-scale 0.5 --reference-spp 256 --reference-bounces 4 --variants-only $V" bash bench/tradeoff-run.sh > /dev/null 2>&1 ) &
done
sleep 2
true
true
wait
for d in ${DATASETS:-mr-head ct-head-cthead phantom ct-aorta}; do
  cp /tmp/cv/tradeoff-$d.log $OUT/ ; cp /tmp/cv/tradeoff-$d/tradeoff.md $OUT/tradeoff-$d.md 2>/dev/null
  echo "$d: $(grep -c '^  [a-z]' $OUT/tradeoff-$d.log) runs"
done
