#!/usr/bin/env bash
# A time series played through the service (issue 59; docs/performance.md, "Time series"): cinevol-server holds a
# cardiac cine (the shared Sunnybrook series: 20 phases of 256x256x12), and `cinevol play` streams it at 1280x720
# for $SECONDS_PER_RUN seconds three ways: still (phase 0, refining), playing at 30 phases a second (a phase switch
# every 33 ms), and playing in the series' own time (real time). Frames a second, latency and the server's frame
# times from each run's CSV.
#   BACKEND=cuda BIN=/tmp/cv/bin DATA=/tmp/cv/data bash bench/time-series-run.sh   (on the GPU machine, from a bundle)
#   BACKEND=cpu WIDTH=320 HEIGHT=180 bash bench/time-series-run.sh                   (here: build/)
# PHASE_COPIES_MB=N gives the server --max-phase-copies-mb N: the phases held on the device in a window built ahead.
# Writes a table to $OUT/time-series.md (default ./bench-out) and logs beside it.
set -uo pipefail
cd "$(dirname "$0")/.." || exit 1
. scripts/wait-for-port.sh
out=${OUT:-bench-out}
mkdir -p "$out"
bin=${BIN:-build}
data=${DATA:-../shared/data}
backend=${BACKEND:-cpu}
seconds=${SECONDS_PER_RUN:-10}
width=${WIDTH:-1280}
height=${HEIGHT:-720}
series=4d-mr-cardiac-cine-sunnybrook/dicom
port_file=$(mktemp -u)

"$bin/cinevol-server" --listen 127.0.0.1:0 --port-file "$port_file" --backend "$backend" --data-root "$data" \
  ${PHASE_COPIES_MB:+--max-phase-copies-mb "$PHASE_COPIES_MB"} > "$out/time-series-server.log" 2>&1 &
server=$!
trap 'kill -TERM $server 2>/dev/null; wait $server 2>/dev/null; rm -f "$port_file"' EXIT
wait_for_port "$port_file" $server 60 "$out/time-series-server.log"
address=127.0.0.1:$(cat "$port_file")

run() {  # run NAME TIME_JSON: plays the series with that Scene.time for $seconds; prints the play line
  local script="$out/$1.jsonl"
  {
    printf '{"session": {"load": "%s", "viewport": {"width": %d, "height": %d}}}\n' "$series" "$width" "$height"
    printf '{"at": 0, "time": %s}\n' "$2"
    printf '{"at": %s, "time": {"phase": 0}}\n' "$seconds"  # stopped: the play ends at its final frame
  } > "$script"
  "$bin/cinevol" play --server "$address" --script "$script" --out "$out/$1" --timeout $((seconds + 120)) \
    > "$out/$1.log" 2>&1 || echo "$1 failed: see $out/$1.log" >&2
  grep '^played' "$out/$1.log" || true
}

still=$(run still '{"phase": 0}')
fast=$(run playing-30 '{"playing": true, "phasesPerSecond": 30}')
real=$(run playing-real-time '{"playing": true}')
fps_of() { sed -n 's/.*(\([0-9.]*\) fps).*/\1/p' <<< "$1"; }
frames_of() { sed -n 's/.* events, \([0-9]*\) frames in .*/\1/p' <<< "$1"; }
latency_of() { sed -n 's/.*latency p50\/p95\/p99 \([0-9.\/]*\) ms.*/\1/p' <<< "$1"; }
{
  echo "| ${width}x${height}, ${seconds} s | frames | frames/s | the time event's latency (ms) |"
  echo "|---|---|---|---|"
  echo "| still (phase 0: refines to its final frame, then idles) | $(frames_of "$still") | $(fps_of "$still") | $(latency_of "$still") |"
  echo "| playing, 30 phases/s | $(frames_of "$fast") | $(fps_of "$fast") | $(latency_of "$fast") |"
  echo "| playing, the series' own time | $(frames_of "$real") | $(fps_of "$real") | $(latency_of "$real") |"
  echo
  for run in still playing-30 playing-real-time; do  # the server's mean frame times, from the play's CSV
    awk -F, -v r="$run" 'NR > 1 && $9 > 0 {n++; rs += $9; sv += $14}
      END {if (n) printf "%s: %d frames, mean render %.2f ms, server %.2f ms\n", r, n, rs / n / 1000, sv / n / 1000}' \
      "$out/$run/frames.csv"
  done
  echo
  echo "backend $backend; $(nproc) CPU cores; $(nvidia-smi --query-gpu=name --format=csv,noheader 2>/dev/null | head -1)" \
    "${PHASE_COPIES_MB:+; --max-phase-copies-mb $PHASE_COPIES_MB}"
  grep -h "volume .*phases" "$out/time-series-server.log" | head -1
} | tee "$out/time-series.md"
