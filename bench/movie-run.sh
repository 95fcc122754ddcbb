#!/usr/bin/env bash
# Stills and movies through the service (docs/performance.md, "Stills and movies"): cinevol-server on one volume,
# then a 512x512 still from the volume cold (the server's first: read, prepared and put on the device) and held
# (the same again), and a 1280x720 orbit movie (RenderMovie), timed end to end by the client.
#   BACKEND=cuda BIN=/tmp/cv/bin VOLUME=... bash bench/movie-run.sh      (on the GPU machine, from the bundle)
#   BACKEND=cpu SPP=8 MOVIE_SECONDS=1 bash bench/movie-run.sh             (here: build/)
# Writes a table to $OUT/movie.md (default ./bench-out) and logs beside it.
set -uo pipefail
cd "$(dirname "$0")/.." || exit 1
. scripts/wait-for-port.sh
out=${OUT:-bench-out}
mkdir -p "$out"
bin=${BIN:-build}
backend=${BACKEND:-cpu}
volume=${VOLUME:-../shared/data/ct-head-cthead/DERIVED_CThead.nhdr}
spp=${SPP:-64}
seconds=${MOVIE_SECONDS:-4}
fps=${FPS:-25}
port_file=$(mktemp -u)

"$bin/cinevol-server" --listen 127.0.0.1:0 --port-file "$port_file" --backend "$backend" --volume "$volume" \
  > "$out/movie-server.log" 2>&1 &
server=$!
trap 'kill -TERM $server 2>/dev/null; wait $server 2>/dev/null; rm -f "$port_file"' EXIT
wait_for_port "$port_file" $server 60 "$out/movie-server.log"
address=127.0.0.1:$(cat "$port_file")

timed() {  # timed LABEL COMMAND...: seconds the command took, its output to the log
  local start end
  start=$(date +%s.%N)
  "${@:2}" >> "$out/movie-client.log" 2>&1 || echo "$1 failed: see $out/movie-client.log" >&2
  end=$(date +%s.%N)
  awk -v a="$start" -v b="$end" 'BEGIN{print b - a}'
}

cold=$(timed cold "$bin/cinevol" snapshot --server "$address" --width 512 --height 512 \
  --spp "$spp" --out "$out/still-cold.png")
held=$(timed held "$bin/cinevol" snapshot --server "$address" --width 512 --height 512 \
  --spp "$spp" --out "$out/still-held.png")
movie=$(timed movie "$bin/cinevol" movie --server "$address" --orbit 360 --seconds "$seconds" \
  --fps "$fps" --width 1280 --height 720 --spp "$spp" --out "$out/orbit.mp4")
{
  echo "| backend | volume | 512x512 still, cold (s) | held (s) | 720p movie: ${seconds} s at ${fps} frames/s (s) | seconds per second of video |"
  echo "|---|---|---|---|---|---|"
  printf "| %s | %s | %.2f | %.2f | %.1f | %.1f |\n" "$backend" "$(basename "$volume")" "$cold" "$held" "$movie" \
    "$(awk -v m="$movie" -v s="$seconds" 'BEGIN{print m / s}')"
  echo
  echo "$spp spp a pixel for the stills and each frame; $(nproc) CPU cores; $(nvidia-smi --query-gpu=name --format=csv,noheader 2>/dev/null | head -1)"
} | tee "$out/movie.md"
