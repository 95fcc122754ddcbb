#!/usr/bin/env bash
# Nsight Compute figures of the render and denoise kernels on the GPU machine
# (docs/performance.md): for each scene, the path tracer's kernel (active
# lanes, occupancy, registers, spills, duration) and the time of every kernel
# of the denoisers. Uses the bundle of bench/make-gpu-bundle.sh; writes
# $OUT/profile-*.txt (or ./gpu-out) and prints the main figures.
#   SCENES="ct-aorta-bone:aorta_ct_cropped.nii.gz" bash bench/profile-run.sh
# RENDER=0 skips the path tracer's sections; DETAIL="WrlsTemporalPass AtrousPass"
# adds each named denoiser kernel's throughput, occupancy and warp-state sections
# (one launch after warm-up), for a pass whose time is to be cut.
set -uo pipefail
cd "$(dirname "$0")/.."
out=${OUT:-gpu-out}
mkdir -p "$out" /tmp/cv
[ -x /tmp/cv/bin/cinevol-bench ] || tar xJf .gpu/bundle.tar.xz -C /tmp/cv
export LD_LIBRARY_PATH=/tmp/cv/lib
bin=/tmp/cv/bin data=/tmp/cv/data
ncu=$(command -v ncu || ls /usr/local/cuda/bin/ncu 2>/dev/null)
[ -n "$ncu" ] || { echo "no ncu on this machine"; exit 2; }

for scene in ${SCENES:-ct-aorta-bone:aorta_ct_cropped.nii.gz ct-head-cthead:ct-head-cthead/DERIVED_CThead.nhdr}; do
  name=${scene%%:*} volume=$data/${scene#*:}
  if [ "${RENDER:-1}" = 1 ]; then
    # The path tracer: the fourth launch of its kernel (after warm-up).
    "$ncu" --kernel-name regex:RenderKernel --launch-skip 3 --launch-count 1 \
      --section SpeedOfLight --section Occupancy --section LaunchStats --section WarpStateStats \
      --section SourceCounters --section MemoryWorkloadAnalysis \
      "$bin/${BENCH:-cinevol-bench}" render --scene "bench/scenes/$name.json" --volume "$volume" --backend cuda \
      --frames 4 --warmup 1 > "$out/profile-render-$name.txt" 2>&1
    echo "== $name: path tracer"
    grep -E "^  [A-Za-z]+Kernel|Duration|Registers Per Thread|Achieved Occupancy|Theoretical Occupancy|Avg. Active Threads Per Warp|Avg. Not Predicated Off Threads|Local Memory Spilling|Compute \(SM\) Throughput|Memory Throughput" \
      "$out/profile-render-$name.txt" | head -20
  fi
  # Every kernel of the denoise benchmark (all its methods on a short orbit), each with its mean time.
  "$ncu" --launch-count 4000 --metrics gpu__time_duration.sum \
    "$bin/cinevol-bench" denoise --scene "bench/scenes/$name.json" --volume "$volume" --backend cuda \
    --frames 10 --warmup 2 --reference-spp 0 > "$out/profile-denoise-$name.txt" 2>&1
  echo "== $name: kernels of the denoisers, mean us over launches"
  awk '/Context [0-9]+, Stream/ {k=$0; if (match(k, /<[^<>]*>/)) k=substr(k, RSTART+1, RLENGTH-2); else {sub(/^ +/, "", k); sub(/\(.*/, "", k)}}
       /gpu__time_duration.sum/ {u=$(NF-1); v=$NF; if (u=="ms") v*=1000; if (u=="ns") v/=1000; s[k]+=v; n[k]++}
       END {for (k in s) printf "%8.1f us x%d %s\n", s[k]/n[k], n[k], k}' "$out/profile-denoise-$name.txt" | sort -rn | head -25
  for kernel in ${DETAIL:-}; do
    "$ncu" --kernel-name-base demangled --kernel-name "regex:$kernel" --launch-skip 20 --launch-count 1 \
      --section SpeedOfLight --section Occupancy --section LaunchStats --section WarpStateStats \
      --section ComputeWorkloadAnalysis --section MemoryWorkloadAnalysis \
      "$bin/cinevol-bench" denoise --scene "bench/scenes/$name.json" --volume "$volume" --backend cuda \
      --frames 10 --warmup 2 --reference-spp 0 > "$out/profile-$kernel-$name.txt" 2>&1
    echo "== $name: $kernel"
    grep -E "Duration|Registers Per Thread|Achieved Occupancy|Compute \(SM\) Throughput|Memory Throughput|DRAM Throughput|L1/TEX Hit Rate|Warp Cycles Per Issued" \
      "$out/profile-$kernel-$name.txt" | head -12
  done
done
