#!/usr/bin/env bash
# Renders by URL under load (issue 58, docs/performance.md, "Renders by URL"): Orthanc seeded with a shared CT
# series (bench/orthanc-seeded.sh), cinevol-server (CPU) naming it, cinevol-web in front, all on loopback; then
#   cold      a 512x512 rendered3D of the series the server does not hold yet (fetched, read, rendered)
#   held      the same again (the series held)
#   alone     a neighbour: one 640x360 interactive session (`cinevol loadtest`, an orbit), its frame rate
#   crowded   the neighbour again while REQUESTS rendered3D requests (default 50, 128x128) arrive at once:
#             its frame rate, and when the requests were answered (first, median, last) and with what status
#   bash bench/rendered-run.sh
# SERIES: the DICOM folder (default the 512x512x20 CT); QUALITY of the requests (default 30: 8 spp).
set -euo pipefail
cd "$(dirname "$0")/.."
. scripts/wait-for-port.sh
bin=${BIN:-build}
series=${SERIES:-../shared/data/ct-body-totalsegmentator/example_ct_dicom}
requests=${REQUESTS:-50}
quality=${QUALITY:-30}
seconds=${SECONDS_PER_RUN:-20}
# shellcheck source=bench/orthanc-seeded.sh
. bench/orthanc-seeded.sh
"$bin/cinevol-server" --listen 127.0.0.1:0 --port-file "$work/port" --backend cpu --pacs "bench=$url" \
  > "$work/server.log" 2>&1 &
pids+=($!)
wait_for_port "$work/port" "${pids[-1]}" 30 "$work/server.log"
address=127.0.0.1:$(cat "$work/port")
# The requests all come from loopback: the gateway's limit of connections from one address (32 by default, against
# one client holding them all) is raised so that they stand for REQUESTS clients.
"$bin/cinevol-web" --listen 127.0.0.1:0 --port-file "$work/web.port" --server "$address" \
  --max-connections-per-address $((requests + 8)) > "$work/web.log" 2>&1 &
pids+=($!)
wait_for_port "$work/web.port" "${pids[-1]}" 30 "$work/web.log"
rendered="http://127.0.0.1:$(cat "$work/web.port")/dicom-web/bench/studies/$study/series/$uid/rendered3D"
echo "series: $instances instances ($series); $(nproc) cores; load average $(cut -d' ' -f1-3 /proc/loadavg)"

fetch() {  # fetch SIZE OUT: status and seconds
  curl -s -o "$2" -w '%{http_code} %{time_total}\n' --max-time 600 \
    "$rendered?orientation=a&viewport=$1,$1&quality=$quality&accept=image/jpeg"
}
read -r cold_status cold < <(fetch 512 "$work/cold.jpg")
read -r held_status held < <(fetch 512 "$work/held.jpg")
printf "| rendered3D 512x512, quality %s | status | seconds |\n|---|---|---|\n| cold | %s | %.2f |\n| held | %s | %.2f |\n\n" \
  "$quality" "$cold_status" "$cold" "$held_status" "$held"

neighbour() {  # neighbour OUT: one interactive session's frames per second over SECONDS_PER_RUN
  "$bin/cinevol" loadtest --server "$address" --sessions 1 --seconds "$seconds" --width 640 --height 360 --json \
    > "$1"
  python3 -c 'import json,sys; r=json.load(open(sys.argv[1])); o=r["overall"]; print("%.1f frames/s, latency p50 %.0f ms, p95 %.0f ms" % (o["fps_mean"], o["latency_ms"]["p50"], o["latency_ms"]["p95"]))' "$1"
}
alone=$(neighbour "$work/alone.json")
neighbour "$work/crowded.json" > "$work/crowded.fps" &
crowd=$!
sleep 2
fetches=()
for i in $(seq "$requests"); do
  fetch 128 "$work/r$i.jpg" > "$work/r$i.txt" &
  fetches+=("$!")
done
wait "${fetches[@]}" "$crowd"
crowded=$(cat "$work/crowded.fps")
statuses=$(cut -d' ' -f1 "$work"/r*.txt | sort | uniq -c | awk '{printf "%s x %s; ", $1, $2}')
times=$(cut -d' ' -f2 "$work"/r*.txt | sort -g)
printf "| neighbour, 640x360 | frames/s, event to frame |\n|---|---|\n| alone | %s |\n| with %s rendered requests | %s |\n\n" \
  "$alone" "$requests" "$crowded"
printf "%s rendered3D requests at once (128x128, quality %s): %sanswered after %.1f s (first), %.1f s (median), %.1f s (last)\n" \
  "$requests" "$quality" "$statuses" "$(echo "$times" | head -1)" "$(echo "$times" | median)" "$(echo "$times" | tail -1)"
