#!/usr/bin/env bash
# A shared session on the GPU machine (docs/performance.md, "A shared
# session"): cinevol-server on CUDA with a real CT, one 1280x720 session
# orbiting (wRLS, 2 spp, camera events at 120 Hz) shared with V viewers
# watching by a link, for each V in $VIEWERS, one server run each. Reports
# the presenter's fps and latency and the viewers' fps. Uses the bundle of
# bench/make-gpu-bundle.sh; writes $OUT/sharing.md (or ./gpu-out).
#   VIEWERS="0 1 10 50" SECONDS_PER_RUN=10 bash bench/sharing-run.sh
set -uo pipefail
cd "$(dirname "$0")/.."
. scripts/wait-for-port.sh
out=${OUT:-gpu-out}
runs=/tmp/cv/sharing-runs
mkdir -p "$out" "$runs"
[ -x /tmp/cv/bin/cinevol-server ] || tar xJf .gpu/bundle.tar.xz -C /tmp/cv
export LD_LIBRARY_PATH=/tmp/cv/lib
bin=/tmp/cv/bin
volume=${VOLUME:-/tmp/cv/data/ct-head-cthead/DERIVED_CThead.nhdr}
scene=${SCENE:-bench/scenes/ct-head-cthead.json}
seconds=${SECONDS_PER_RUN:-10}

for v in ${VIEWERS:-0 1 10 50}; do
  port_file=/tmp/cv/sharing-port-$v
  rm -f "$port_file"
  "$bin/cinevol-server" --listen 127.0.0.1:0 --port-file "$port_file" --backend cuda --volume "$volume" \
    --max-viewers-per-session 1000 > "$runs/server-$v.log" 2>&1 &
  server=$!
  wait_for_port "$port_file" $server 30 "$runs/server-$v.log"
  "$bin/cinevol" loadtest --server "127.0.0.1:$(cat "$port_file")" --sessions 1 --viewers "$v" \
    --seconds "$seconds" --width 1280 --height 720 --spp 2 --denoiser wrls --scene "$scene" \
    > "$runs/loadtest-$v.md" 2>&1
  echo "sharing viewers=$v rc=$?"
  kill -TERM $server
  wait $server
  { echo "#### one session, $v viewers"; cat "$runs/loadtest-$v.md"; echo; } >> "$out/sharing.md"
done
cat "$out/sharing.md"
