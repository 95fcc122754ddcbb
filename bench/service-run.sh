#!/usr/bin/env bash
# The render service under load on the GPU machine (docs/performance.md):
# cinevol-server on CUDA with a real CT, then `cinevol loadtest` with N
# concurrent 1280x720 sessions orbiting their cameras (wRLS, 2 spp), while
# GPU and CPU utilisation are sampled. Uses the bundle of
# bench/make-gpu-bundle.sh; writes tables and logs to $OUT (or ./gpu-out).
#   SESSIONS="1 4 8 16" SECONDS_PER_RUN=10 bash bench/service-run.sh
# SERVER=path runs another build's cinevol-server (e.g. the previous release,
# to rerun its table in the same session); LABEL names its files and rows.
# EXTRA adds loadtest flags (e.g. "--interactive-frame-ms 16"), SERVER_EXTRA
# server flags (e.g. "--encode-threads 1": every frame encodes whole);
# WORKERS sets --workers-per-gpu (default: the server's).
set -uo pipefail
cd "$(dirname "$0")/.."
. scripts/wait-for-port.sh
out=${OUT:-gpu-out}
runs=/tmp/cv/service-runs  # per-run logs; the tables go to $out/service.md
mkdir -p "$out" "$runs"
[ -x /tmp/cv/bin/cinevol-server ] || tar xJf .gpu/bundle.tar.xz -C /tmp/cv
export LD_LIBRARY_PATH=/tmp/cv/lib
bin=/tmp/cv/bin
volume=${VOLUME:-/tmp/cv/data/ct-head-cthead/DERIVED_CThead.nhdr}
scene=${SCENE:-bench/scenes/ct-head-cthead.json}
seconds=${SECONDS_PER_RUN:-10}
server_bin=${SERVER:-$bin/cinevol-server}
label=${LABEL:-new}

# Busy share of all CPUs between two reads of /proc/stat.
cpu_ticks() { awk '/^cpu /{print $2+$3+$4+$7+$8+$9, $2+$3+$4+$5+$6+$7+$8+$9}' /proc/stat; }

run() {  # run N [WORKERS_PER_GPU] (none: the server's default)
  local n=$1 workers=${2:-} port_file=/tmp/cv/port-$1-${2:-default}
  local tag=$label-$n-${workers:-default}
  rm -f "$port_file"
  "$server_bin" --listen 127.0.0.1:0 --port-file "$port_file" --backend cuda --volume "$volume" \
    ${workers:+--workers-per-gpu "$workers"} --max-sessions 256 --max-sessions-per-principal 256 \
    --max-total-pixels 300000000 ${SERVER_EXTRA:-} > "$runs/server-$tag.log" 2>&1 &
  local server=$!
  wait_for_port "$port_file" $server 30 "$runs/server-$tag.log"
  nvidia-smi --query-gpu=utilization.gpu,memory.used --format=csv,noheader,nounits -lms 200 > "$runs/gpu-util-$tag.txt" &
  local smi=$!
  read -r busy0 total0 < <(cpu_ticks)
  "$bin/cinevol" loadtest --server "127.0.0.1:$(cat "$port_file")" --sessions "$n" --seconds "$seconds" \
    --width 1280 --height 720 --spp 2 --denoiser wrls --scene "$scene" ${EXTRA:-} > "$runs/loadtest-$tag.md" 2>&1
  echo "loadtest $label N=$n workers=$workers rc=$?"
  read -r busy1 total1 < <(cpu_ticks)
  kill $smi
  kill -TERM $server
  wait $server
  local gpu mem cpu
  gpu=$(awk -F', ' '$1>0{s+=$1;n++} END{printf "%.0f", n?s/n:0}' "$runs/gpu-util-$tag.txt")
  mem=$(awk -F', ' '$2>m{m=$2} END{print m+0}' "$runs/gpu-util-$tag.txt")
  cpu=$(awk -v b="$((busy1-busy0))" -v t="$((total1-total0))" 'BEGIN{printf "%.0f", 100*b/t}')
  { echo "#### $label, $n sessions"
    cat "$runs/loadtest-$tag.md"
    echo "GPU utilisation (nvidia-smi, mean of non-zero samples): ${gpu}%; GPU memory used (peak): ${mem} MiB; CPU busy (all $(nproc) cores, server and client): ${cpu}%; workers per GPU: ${workers:-the default}"
    echo; } >> "$out/service.md"
}

nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv,noheader | tee "$out/gpu.txt"
for n in ${SESSIONS:-1 4 8 16}; do run "$n" "${WORKERS:-}"; done
for n in ${SERIAL_SESSIONS-8}; do run "$n" 1; done  # one worker: sessions' CUDA work serialised
cat "$out/service.md"
