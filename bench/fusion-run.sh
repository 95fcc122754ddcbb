#!/usr/bin/env bash
# What fusing a second volume costs (issue 59; docs/performance.md, "Fusion"): cinevol-server holds the shared
# PET/CT study (CT 512x512x135, PET 128x128x135 in SUVbw), and `cinevol play` orbits the CT at 1280x720 for
# $SECONDS_PER_RUN seconds twice, a camera event a frame interval apart: the CT alone, then with the PET fused (its
# glow above SUVbw 2.5, as the page's default). Frames a second, latency and the server's frame times of each.
#   BACKEND=cuda BIN=/tmp/cv/bin DATA=/tmp/cv/data bash bench/fusion-run.sh   (on the GPU machine, from a bundle)
#   BACKEND=cpu WIDTH=320 HEIGHT=180 bash bench/fusion-run.sh                   (here: build/)
# Writes a table to $OUT/fusion.md (default ./bench-out) and logs beside it.
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
study=$data/pet-ct-acrin-nsclc-fdg
port_file=$(mktemp -u)

"$bin/cinevol-server" --listen 127.0.0.1:0 --port-file "$port_file" --backend "$backend" \
  --volume "$study/ct" --volume "$study/pet-ac" > "$out/fusion-server.log" 2>&1 &
server=$!
trap 'kill -TERM $server 2>/dev/null; wait $server 2>/dev/null; rm -f "$port_file"' EXIT
wait_for_port "$port_file" $server 120 "$out/fusion-server.log"
address=127.0.0.1:$(cat "$port_file")

glow='{"volumeId": "pet-ac", "suv": true, "overlay": {"colorMap": "HOT", "opacity": 0.5},
  "transferFunction": {"densityScale": 1, "points": [
    {"value": 2.5, "opacity": 0, "diffuse": {"r": 1, "g": 0.4, "b": 0.1}},
    {"value": 10, "opacity": 0.4, "diffuse": {"r": 1, "g": 0.4, "b": 0.1}, "emission": {"r": 6, "g": 2.4, "b": 0.5}}]}}'

run() {  # run NAME FUSION_JSON: orbits the CT for $seconds, 60 camera events a second; prints the play line
  local script="$out/$1.jsonl" scene="$out/$1-scene.json"
  printf '{"transferFunction": {"preset": "ct-bone"}%s}\n' "${2:+, \"fusion\": $2}" > "$scene"
  {
    printf '{"session": {"volume": "ct", "scene": "%s", "viewport": {"width": %d, "height": %d}}}\n' \
      "$(basename "$scene")" "$width" "$height"
    awk -v s="$seconds" 'BEGIN {for (i = 0; i < s * 60; i++) {a = i / 60 * 0.5;
      printf "{\"at\": %.4f, \"camera\": {\"eye\": {\"x\": %.2f, \"y\": %.2f, \"z\": 0}, \"target\": {}, \"up\": {\"z\": 1}, \"fovYDeg\": 30}}\n",
        i / 60, 900 * sin(a), -900 * cos(a)}}'
  } > "$script"
  "$bin/cinevol" play --server "$address" --script "$script" --out "$out/$1" --timeout $((seconds + 120)) \
    > "$out/$1.log" 2>&1 || echo "$1 failed: see $out/$1.log" >&2
  grep '^played' "$out/$1.log" || true
}

alone=$(run ct-alone "")
fused=$(run ct-pet-fused "$glow")
fps_of() { sed -n 's/.*(\([0-9.]*\) fps).*/\1/p' <<< "$1"; }
latency_of() { sed -n 's/.*latency p50\/p95\/p99 \([0-9.\/]*\) ms.*/\1/p' <<< "$1"; }
{
  echo "| ${width}x${height}, an orbit of ${seconds} s | frames/s | camera event's latency p50/p95/p99 (ms) |"
  echo "|---|---|---|"
  echo "| CT alone | $(fps_of "$alone") | $(latency_of "$alone") |"
  echo "| CT with the PET fused (SUVbw glow) | $(fps_of "$fused") | $(latency_of "$fused") |"
  echo
  for run in ct-alone ct-pet-fused; do  # the server's mean frame times, from the play's CSV
    awk -F, -v r="$run" 'NR > 1 && $9 > 0 {n++; rs += $9; sv += $14}
      END {if (n) printf "%s: %d frames, mean render %.2f ms, server %.2f ms\n", r, n, rs / n / 1000, sv / n / 1000}' \
      "$out/$run/frames.csv"
  done
  echo
  echo "backend $backend; $(nproc) CPU cores; $(nvidia-smi --query-gpu=name --format=csv,noheader 2>/dev/null | head -1)"
} | tee "$out/fusion.md"
