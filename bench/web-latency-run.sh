#!/usr/bin/env bash
# The browser's path measured without a browser (issue 61, docs/performance.md
# "The browser's path"): one cinevol-server (BACKEND, default auto) on CThead,
# cinevol-web in front of it, and build/web/bench/motion-to-photon.mjs: a node
# client that talks as the page does (gRPC-web over HTTP/1.1 through the
# gateway) and, for comparison, straight to the server (gRPC), an orbit of
# camera events at 30 a second at 1280x720 on each path; motion-to-photon
# p50/p95 per path and the gateway's added latency. Everything on loopback,
# stopped by pid.
#   bash bench/web-latency-run.sh
# BIN: the programs' folder (default build); NODE: node (default node);
# VOLUME, SCENE: the volume and its scene (default CThead); SECONDS_PER_RUN
# (default 10); WIDTH, HEIGHT (default 1280x720); STREAM: the sessions'
# StreamSettings as JSON (default wRLS).
set -euo pipefail
cd "$(dirname "$0")/.."
. scripts/wait-for-port.sh
bin=${BIN:-build}
node=${NODE:-node}
out=$(mktemp -d)
volume=${VOLUME:-../shared/data/ct-head-cthead/DERIVED_CThead.nhdr}
scene=$(realpath "${SCENE:-bench/scenes/ct-head-cthead.json}")

"$bin/cinevol-server" --listen 127.0.0.1:0 --port-file "$out/server.port" --backend "${BACKEND:-auto}" \
  --volume "$volume" > "$out/server.log" 2>&1 &
server=$!
web=
trap 'kill -TERM $server ${web:+$web} 2>/dev/null; wait; rm -rf "$out"' EXIT
wait_for_port "$out/server.port" $server 60 "$out/server.log"
"$node" "$bin/web/gateway.mjs" --static "$bin/web/static" --listen 127.0.0.1:0 --port-file "$out/web.port" \
  --server "127.0.0.1:$(cat "$out/server.port")" > "$out/web.log" 2>&1 &
web=$!
wait_for_port "$out/web.port" $web 30 "$out/web.log"
echo "$bin/cinevol-server and cinevol-web on loopback, $(nproc) cores, load $(cut -d' ' -f1-3 /proc/loadavg)"
"$node" "$bin/web/bench/motion-to-photon.mjs" --gateway "127.0.0.1:$(cat "$out/web.port")" \
  --server "127.0.0.1:$(cat "$out/server.port")" --volume "$(basename "${volume%.*}")" --scene "$scene" \
  --seconds "${SECONDS_PER_RUN:-10}" --width "${WIDTH:-1280}" --height "${HEIGHT:-720}" \
  --stream "${STREAM:-{\"denoiser\": \"DENOISER_WRLS\"\}}"
