#!/usr/bin/env bash
# A series from a PACS to the first frame (issue 34, docs/performance.md):
# Debian's Orthanc with its DICOMweb plugin on a free loopback port, seeded
# with a shared DICOM series (UIDs stamped with DCMTK's dcmodify, as the
# shared series lack them), then for each count of parallel fetches a fresh
# cinevol-server (CPU) naming it:
#   orthanc   Orthanc's own WADO-RS retrieve of the series with curl, the bytes
#             thrown away: what no client of this PACS can beat here
#   disk      the same files loaded from the disk (`cinevol volumes load`)
#   load      `cinevol pacs load`: listing, limits, parallel retrieve, the
#             reader cage reading the folder, the volume held
#   first     the session's first frame after CreateSession (`cinevol play`)
#   bash bench/pacs-run.sh
# SERIES: the folder of DICOM files (default the 512x512x20 JPEG 2000 CT);
# FETCHES: the parallel fetches to try (default "1 2 4 8"); RUNS (3): runs
# of each, the median printed. Servers stop by pid; everything on loopback.
set -euo pipefail
cd "$(dirname "$0")/.."
. scripts/wait-for-port.sh
bin=${BIN:-build}
series=${SERIES:-../shared/data/ct-body-totalsegmentator/example_ct_dicom}
fetches=${FETCHES:-1 2 4 8}
runs=${RUNS:-3}
# shellcheck source=bench/orthanc-seeded.sh
. bench/orthanc-seeded.sh
bytes=$(du -cb "$work"/series/*.dcm | tail -1 | cut -f1)
echo "series: $instances instances, $((bytes / 1024)) KiB ($series); $(nproc) cores; load average $(cut -d' ' -f1-3 /proc/loadavg)"

for _ in $(seq "$runs"); do
  t0=$(now)
  curl -sf -H 'Accept: multipart/related; type="application/dicom"; transfer-syntax=*' \
    "$url/studies/$study/series/$uid" -o /dev/null
  echo "$(now) - $t0" | bc
done | median | xargs printf "orthanc retrieve (curl, one request): %.3f s\n"

# The same files read from the disk (LoadVolume of the folder): the reader cage's share.
"$bin/cinevol-server" --listen 127.0.0.1:0 --port-file "$work/port" --backend cpu --data-root "$work" \
  > "$work/server.log" 2>&1 &
server=$!
pids+=($server)
wait_for_port "$work/port" $server 30 "$work/server.log"
for _ in $(seq "$runs"); do
  t0=$(now)
  "$bin/cinevol" volumes load --server "127.0.0.1:$(cat "$work/port")" series > /dev/null
  echo "$(now) - $t0" | bc
  "$bin/cinevol" volumes unload --server "127.0.0.1:$(cat "$work/port")" series > /dev/null
done | median | xargs printf "the same files from the disk (cinevol volumes load): %.3f s\n"
kill "$server"
wait "$server" 2> /dev/null || true
rm -f "$work/port"

echo '{"session": {"viewport": {"width": 1280, "height": 720}, "stream": {"targetSpp": 2}}}' > "$work/script.jsonl"
printf "| parallel fetches | load s | first frame s |\n|---|---|---|\n"
for p in $fetches; do
  loads=() firsts=()
  for run in $(seq "$runs"); do
    "$bin/cinevol-server" --listen 127.0.0.1:0 --port-file "$work/port" --backend cpu --pacs "bench=$url" \
      --pacs-parallel-fetches "$p" > "$work/server.log" 2>&1 &
    server=$!
    pids+=($server)
    wait_for_port "$work/port" $server 30 "$work/server.log"
    address=127.0.0.1:$(cat "$work/port")
    t0=$(now)
    id=$("$bin/cinevol" pacs load --server "$address" --pacs bench --study "$study" --series "$uid" --json |
      python3 -c 'import json,sys; print(json.load(sys.stdin)["id"])')
    loads+=("$(echo "$(now) - $t0" | bc)")
    "$bin/cinevol" play --server "$address" --script "$work/script.jsonl" --volume "$id" --out "$work/play" \
      --timeout 120 > /dev/null
    firsts+=("$(sed -n 2p "$work/play/frames.csv" | cut -d, -f2)")
    kill "$server"
    wait "$server" 2> /dev/null || true
    rm -f "$work/port"
  done
  printf "| %s | %.2f | %.2f |\n" "$p" "$(printf '%s\n' "${loads[@]}" | median)" \
    "$(printf '%s\n' "${firsts[@]}" | median)"
done
