#!/usr/bin/env bash
# The screenshots of docs/viewer.md: a local CPU cinevol-server on a small
# head phantom (and the shared data, for a real CT), cinevol-viewer under
# Xvfb playing examples/scripts/viewer-*.jsonl, and the banner of a viewer
# whose server is down. About 3 minutes on 2 cores.
#   bash bench/viewer-screenshots.sh
#   BIN=/tmp/cv/bin DATA=/data bash bench/viewer-screenshots.sh
set -euo pipefail
cd "$(dirname "$0")/.."
. scripts/wait-for-port.sh
root=$PWD
bin=$root/${BIN:-build}
data=${DATA:-../shared/data}
out=$root/${OUT:-docs/viewer}
size=(--width "${WIDTH:-1100}" --height "${HEIGHT:-620}")
mkdir -p "$out"
work=$(mktemp -d)  # the viewer's working folder: mid-script screenshots, layout files, the server's log
port_file=$work/port
server_args=(--listen 127.0.0.1:0 --port-file "$port_file" --backend "${BACKEND:-cpu}" --volume 'phantom:head?size=96')
[ -d "$data" ] && server_args+=(--data-root "$data")
"$bin/cinevol-server" "${server_args[@]}" > "$work/server.log" 2>&1 &
server=$!
trap 'kill -TERM $server 2>/dev/null; wait $server 2>/dev/null; rm -rf "$work"' EXIT
wait_for_port "$port_file" $server 30 "$work/server.log"
address=127.0.0.1:$(cat "$port_file")

# viewer ARGS...: the viewer in a 1600x1000 virtual screen, run in $work.
viewer() {
  (cd "$work" && xvfb-run -a -s "-screen 0 1600x1000x24" "$bin/cinevol-viewer" "${size[@]}" --max-seconds 300 "$@")
}

# shoot NAME SCRIPT: plays examples/scripts/SCRIPT, keeps the window at its end as NAME.png.
shoot() {
  viewer --server "$address" --script "$root/examples/scripts/$2" --screenshot "$work/$1.png"
  cp "$work/$1.png" "$out/$1.png"
}

# (a) the main window after a short orbit and a zoom: the tour's first screenshot.
shoot tour-end viewer-tour.jsonl
cp "$work/viewer-tour-1.png" "$out/main.png"
rm "$out/tour-end.png"
# (b) the Lights, Render and Scene panels after Ctrl+drags that turn the key light.
shoot lights-render viewer-lights.jsonl
# (c) a transfer-function edit (window/level, a point moved) on a real CT.
if [ -d "$data/ct-body-totalsegmentator" ]; then
  shoot ct-transfer viewer-ct-transfer.jsonl
else
  echo "no $data/ct-body-totalsegmentator: skipping ct-transfer.png" >&2
fi
# (d) a server that is down: the banner; the viewer gives up with exit code 3.
# Its one step comes a second after the first failure, once the banner has
# grown to the message's height (it does so a frame after the text changes).
unused=$(python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
printf '%s\n' '{"session": {}}' '{"at": 1, "ui": {"panel": {"name": "stats", "open": false}}}' > "$work/down.jsonl"
rc=0
viewer --server "127.0.0.1:$unused" --connect-timeout 1 --script "$work/down.jsonl" --screenshot "$work/server-down.png" ||
  rc=$?
[ "$rc" = 3 ] || { echo "a viewer without its server exited $rc, not 3" >&2; exit 1; }
cp "$work/server-down.png" "$out/server-down.png"
ls -l "$out"
