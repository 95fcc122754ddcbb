#!/usr/bin/env bash
# cinevol-viewer's own cost and its event-to-frame latency while orbiting at
# 1280x720, against a CUDA cinevol-server, beside `cinevol loadtest` on the
# same server (docs/performance.md). The GPU machine has no X server or
# Xvfb: the viewer draws through SDL's offscreen video driver, with each
# renderer in $RENDERERS (opengles2: the GPU through EGL; software).
# Uses the bundle of bench/make-gpu-bundle.sh; writes logs to $OUT.
#   bash bench/viewer-run.sh
set -uo pipefail
cd "$(dirname "$0")/.."
. scripts/wait-for-port.sh
out=${OUT:-gpu-out}
mkdir -p "$out" /tmp/cv
[ -x /tmp/cv/bin/cinevol-viewer ] || tar xJf .gpu/bundle.tar.xz -C /tmp/cv
export LD_LIBRARY_PATH=/tmp/cv/lib
bin=/tmp/cv/bin
volume=${VOLUME:-/tmp/cv/data/ct-head-cthead/DERIVED_CThead.nhdr}
seconds=${SECONDS_PER_RUN:-10}
port_file=/tmp/cv/viewer-port
rm -f "$port_file"
"$bin/cinevol-server" --listen 127.0.0.1:0 --port-file "$port_file" --backend "${BACKEND:-cuda}" --volume "$volume" \
  > "$out/viewer-server.log" 2>&1 &
server=$!
trap 'kill -TERM $server; wait $server' EXIT
wait_for_port "$port_file" $server 30 "$out/viewer-server.log"
address=127.0.0.1:$(cat "$port_file")

# The same orbit for both: 360 degrees at 30 camera events a second.
script=/tmp/cv/orbit.jsonl
printf '%s\n' '{"session": {"viewport": {"width": 1280, "height": 720}, "stream": {"denoiser": "DENOISER_WRLS"}}}' \
  "{\"at\": 0.5, \"orbit\": {\"degrees\": 360, \"seconds\": $seconds, \"hz\": 30}}" > "$script"
"$bin/cinevol" loadtest --server "$address" --sessions 1 --seconds "$seconds" --width 1280 --height 720 --spp 2 \
  --denoiser wrls --script "$script" > "$out/viewer-loadtest.md" 2>&1
echo "loadtest rc=$?"
# The window: a 330-pixel panel beside a 1280x720 frame area.
for renderer in ${RENDERERS:-opengles2 software}; do
  SDL_VIDEODRIVER=offscreen SDL_RENDER_DRIVER=$renderer "$bin/cinevol-viewer" --server "$address" \
    --script "$script" --screenshot "$out/viewer-$renderer.png" --width 1610 --height 720 --max-seconds 60 \
    > "$out/viewer-$renderer.log" 2>&1
  echo "viewer ($renderer) rc=$?: $(grep '^cinevol-viewer:' "$out/viewer-$renderer.log")"
done
cat "$out/viewer-loadtest.md"
