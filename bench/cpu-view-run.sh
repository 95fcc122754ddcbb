#!/usr/bin/env bash
# A live view on a CPU server (issue 32, docs/performance.md): cinevol-server
# --backend cpu on a real CT, one session at 1280x720 (wRLS, the scene's
# 2 spp, the session's default frame budget unless BUDGET sets one):
#   loadtest  `cinevol loadtest`: an orbit of 360 degrees in SECONDS_PER_RUN
#             at 30 camera events a second (a dragging mouse's rate)
#   viewer    cinevol-viewer under Xvfb playing the same orbit (a 330-pixel
#             panel beside a 1280x720 image), on the same cores as the server
#   still     `cinevol play`: a 3 s orbit, then still until the final frame:
#             the time from the last event to the refinement's final frame
#   browser   the page in headless chromium through cinevol-web, the same
#             scene at 1280x720 and an orbit dragged at 30 moves a second
#             (bench/web-view.mjs): motion-to-photon measured in the page
# Prints the load average before each part (the machine is shared: compare
# runs made at a low load) and writes logs to $OUT.
#   bash bench/cpu-view-run.sh
# BIN: the programs' folder (default build); VOLUME, SCENE: the CT and its
# scene (default CThead); RUNS: the parts (default "loadtest viewer still");
# BUDGET: the session's interactiveFrameMs (default: the server's); JPEG: its
# jpegQuality while moving (default 80); AT_RENDERED_SIZE=1: the loadtest's
# and still's frames come at the size they render (framesAtRenderedSize, what
# the viewer and the page ask for), not upsampled by the server.
# RUNS="loadtest viewer browser" compares the three clients on one server.
set -uo pipefail
cd "$(dirname "$0")/.."
. scripts/wait-for-port.sh
root=$PWD
bin=${BIN:-build}
out=${OUT:-cpu-view-out}
volume=${VOLUME:-../shared/data/ct-head-cthead/DERIVED_CThead.nhdr}
scene=$(realpath "${SCENE:-bench/scenes/ct-head-cthead.json}")
seconds=${SECONDS_PER_RUN:-20}
stream='"denoiser": "DENOISER_WRLS"'
[ -n "${BUDGET:-}" ] && stream="$stream, \"interactiveFrameMs\": $BUDGET"
[ -n "${JPEG:-}" ] && stream="$stream, \"jpegQuality\": $JPEG"
[ -n "${AT_RENDERED_SIZE:-}" ] && stream="$stream, \"framesAtRenderedSize\": true"
mkdir -p "$out"
out=$(realpath "$out")

port_file=$out/port
rm -f "$port_file"
"$bin/cinevol-server" --listen 127.0.0.1:0 --port-file "$port_file" --backend cpu --volume "$volume" \
  > "$out/server.log" 2>&1 &
server=$!
trap 'kill -TERM $server; wait $server' EXIT
wait_for_port "$port_file" $server 60 "$out/server.log"
address=127.0.0.1:$(cat "$port_file")
echo "server $address ($bin), $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2)"

orbit=$out/orbit.jsonl
printf '%s\n' "{\"session\": {\"scene\": \"$scene\", \"viewport\": {\"width\": 1280, \"height\": 720}, \"stream\": {$stream}}}" \
  "{\"at\": 0.5, \"orbit\": {\"degrees\": 360, \"seconds\": $seconds, \"hz\": 30}}" > "$orbit"
still=$out/still.jsonl
printf '%s\n' "{\"session\": {\"scene\": \"$scene\", \"viewport\": {\"width\": 1280, \"height\": 720}, \"stream\": {$stream}}}" \
  '{"at": 0.5, "orbit": {"degrees": 45, "seconds": 3, "hz": 30}}' > "$still"

for part in ${RUNS:-loadtest viewer still}; do
  echo "== $part, load average: $(cut -d' ' -f1-3 /proc/loadavg)"
  case $part in
    loadtest)
      "$bin/cinevol" loadtest --server "$address" --sessions 1 --seconds "$seconds" --script "$orbit" \
        > "$out/loadtest.md" 2>&1
      echo "rc=$?"; cat "$out/loadtest.md" ;;
    viewer)
      xvfb-run -a -s "-screen 0 1700x800x24" "$bin/cinevol-viewer" --server "$address" --script "$orbit" \
        --screenshot "$out/viewer.png" --width 1610 --height 720 --max-seconds $((seconds + 60)) \
        > "$out/viewer.log" 2>&1
      echo "rc=$?: $(grep '^cinevol-viewer:' "$out/viewer.log")" ;;
    browser)
      rm -f "$out/web.port"
      "$bin/cinevol-web" --listen 127.0.0.1:0 --port-file "$out/web.port" --server "$address" > "$out/web.log" 2>&1 &
      web=$!
      wait_for_port "$out/web.port" $web 30 "$out/web.log"
      node bench/web-view.mjs --gateway "127.0.0.1:$(cat "$out/web.port")" --volume "$(basename "${volume%.*}")" \
        --scene "$scene" --stream "{$stream}" --seconds "$seconds" --screenshot "$out/browser.png"
      echo "rc=$?"
      kill -TERM $web; wait $web ;;
    still)
      rm -rf "$out/still"
      "$bin/cinevol" play --server "$address" --script "$still" --out "$out/still" --timeout 600 \
        > "$out/still.log" 2>&1
      echo "rc=$?"
      # From the last event's send (its first frame's arrival less its latency)
      # to the final frame's arrival.
      awk -F, 'NR == 1 { for (i = 1; i <= NF; ++i) col[$i] = i; next }
        { seq = $col["last_event_seq"] + 0
          if (seq > last) { last = seq; sent = $col["received_s"] - $col["latency_ms"] / 1000 }
          if ($col["final"] == "1" || $col["final"] == "true") { final = $col["received_s"]; spp = $col["accumulated_spp"] }
          frames++ }
        END { printf "still: final frame %.1f s after the last event, %d spp, %d frames in all\n", final - sent, spp, frames }' \
        "$out/still/frames.csv" ;;
  esac
done
echo "== end, load average: $(cut -d' ' -f1-3 /proc/loadavg)"
