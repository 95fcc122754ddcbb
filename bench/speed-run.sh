#!/usr/bin/env bash
# Issue 61's measurements on the GPU machine, each step's builds alternating
# in one call: the bundle of bench/make-speed-bundle.sh holds this build
# (bin/) and the one before (bin-before/); their libraries are unpacked into
# $CV/lib by the two calls before (see that script).
#   CV=$PWD/.gpu/cv BUNDLE=.gpu/speed/programs STEPS="tests encode pair sweep big admission" bash run.sh
# Steps (each writes logs to $OUT and rows to $OUT/table.md, printed last):
#   tests      the GPU tests of this build (TESTS: a gtest filter)
#   encode     cinevol-bench encode: every JPEG encoder on the same frames
#   pair       loadtests of both builds, alternating: PAIR_SESSIONS (1 32 64) at 1280x720,
#              with PAIR_EXTRA's loadtest flags, PAIR_ROUNDS (1) times
#   sweep      this build's loadtest over SWEEP (1 8 16 32 48 64 96 128) sessions,
#              full size and (SWEEP_INTERACTIVE) with --interactive-frame-ms 33
#   big        one 3840x2160 and one 2560x1440 session, both builds alternating, BIG_RUNS (2) times;
#              with BIG_INTERACTIVE_MS also this build's 3840x2160 with --interactive-frame-ms
#   admission  --min-session-fps 30, ADMIT_SESSIONS (64) arriving over RAMP (8) seconds, each
#              running ADMIT_SECONDS (SECONDS_PER_RUN): the
#              sessions past capacity refused, the rest at >= 30 fps
#   cpujpeg    this build with --jpeg-encoder cpu, CPUJPEG_SESSIONS (1 64)
#   wait       this build with --gpu-wait in WAITS (auto block yield): WAIT_SESSIONS (1 128) full
#              size, WAIT_INTERACTIVE (128) with --interactive-frame-ms 33
#   stretch    this build with --interactive-frame-ms 33 over STRETCH_SESSIONS (64 96 128), STRETCH_RUNS (2)
#              times: frames upsampled by the server (--server-upsamples) and at their rendered
#              size for the client to stretch (the default), alternating
#   stopgo     STOPGO_BUILDS (both) alternating, STOPGO_RUNS (2) times: STOPGO_SESSIONS (32 64) sessions
#              playing bench/scenes/stop-and-go.jsonl (a 60-degree orbit in 1 s, then 0.6 s
#              at rest, looped; --interactive-frame-ms 33), arriving over 1.6 s: frames
#              change size each time a view starts and stops moving
#   tfdrag     both builds alternating, TFDRAG_RUNS (2) times: TFDRAG_SESSIONS (32 64) full-size
#              sessions playing bench/scenes/tf-drag.jsonl (CThead's soft-tissue and bone ramps
#              swept 150 units either way and back in 1 s, 30 transfer-function events a second)
#   sizes      this build's SIZES_SESSIONS (128) sessions at each of SIZES (1280x720 640x360
#              320x180), with SIZES_FLAGS' loadtest flags: what a frame costs that does not grow
#              with its pixels; with SERVER_EXTRA, what a server flag buys at one size
#   kernels    Nsight Compute over one session of this build at KERNELS_SIZE (640x360): each kernel's
#              time, SM time, warps active and shape (bench/kernel_table.py), KERNELS_COUNT (200)
#              launches after the first KERNELS_SKIP (150); ncu from NCU or the CUDA toolkit
#   memory     the device memory per added 720p session (VolumeCache test), of each build
#              whose cinevol_tests the bundle holds
#   identity   both builds' cinevol-bench tradeoff on CThead (640x360, orbit and point light, every
#              denoiser) and refine (a still to 96 spp): the same quality columns and images? (a
#              change that claims the same output; both builds f44c2e1 or later, whose study
#              references share their seeds, or both earlier); where they differ, by how much
#              (bench/compare_tradeoff.py)
#   render     cinevol-bench render of both builds, alternating, RENDER_ROUNDS (2) times: the path
#              tracer's median ms a frame on CThead at 1280x720 (a change to the render alone)
#   study      the trade-off study at 720p (docs/tradeoff.md's 28 runs: --frames-scale 0.5, 256-spp
#              references at 4 bounces, --variants-only) on STUDY_DATASETS (ct-head-cthead mr-head
#              phantom ct-aorta), bin-before then bin and the EXTRA_BUILDS, the references cached
#              once and shared; bench/compare_tradeoff.py of bin-before against each. About 100 s
#              a build and data set on an H100, so two data sets a call; the MR head and the aorta
#              crop from STUDY_DATA (a carried folder holding MR.nii.gz and aorta_ct_cropped.nii.gz)
#   clients    CLIENTS_SESSIONS (8 128) full-size sessions from one loadtest process and from two (CLIENTS=2
#              splits any step's sessions between that many), alternating
# EXTRA_BUILDS: folders under $CV beside bin/ (a call's command puts them there), each holding a
# cinevol-bench and the cinevol-reader it starts, that the render and identity steps measure
# too, against bin-before.
# SECONDS_PER_RUN (8) is each loadtest's length, DENOISER (wrls) its sessions' denoiser, SPP (2) their samples a frame. Every session of a loadtest
# shares one connection: servers allow 1024 streams on it (128 by default, which
# 128 sessions' streams fill, and their closing calls then wait for a stream). This build's servers run with
# --min-session-fps 0 (MIN_FPS) but in the admission step, SERVER_EXTRA adds flags.
set -uo pipefail
. scripts/wait-for-port.sh  # run from the project root (the device runs there)
bundle=${BUNDLE:-.gpu61}
out=${OUT:-gpu-out}
cv=${CV:-/tmp/cv}  # where the bundle is unpacked
logs=$cv/logs  # every run's logs, packed into $out/logs.tar.xz at the end (few files come back)
mkdir -p "$out" "$cv" "$logs"
# Always this bundle's programs: a warm machine may hold another call's.
rm -rf "$cv/bin" "$cv/bin-before" && tar xJf "$bundle/bundle.tar.xz" -C "$cv"
export LD_LIBRARY_PATH=$cv/lib
volume=$cv/data/ct-head-cthead/DERIVED_CThead.nhdr
scene=$cv/scenes/ct-head-cthead.json
seconds=${SECONDS_PER_RUN:-8}
table=$out/table.md
export CINEVOL_SERVER=$cv/bin/cinevol-server CINEVOL_CLI=$cv/bin/cinevol

gpu_name() { nvidia-smi --query-gpu=name --format=csv,noheader | head -1; }

# Every descendant of a process, by id.
descendants() { local child; for child in $(pgrep -P "$1"); do echo "$child"; descendants "$child"; done; }

# CPU seconds (user + system) a process has used so far.
cpu_seconds() { awk '{printf "%.2f", ($14 + $15) / 100}' "/proc/$1/stat" 2>/dev/null || echo 0; }

# loadtest LABEL BUILD SESSIONS WIDTH HEIGHT [LOADTEST FLAGS...]: a fresh server
# of BUILD (bin or bin-before) on CThead, SESSIONS orbiting sessions (or
# playing SCRIPT, whose viewport WIDTH x HEIGHT should name); one row.
loadtest() {
  local label=$1 build=$2 n=$3 w=$4 h=$5
  shift 5
  local tag="$label-$build-$n-${w}x$h" port_file=$cv/port-$RANDOM extra=${SERVER_EXTRA:-}
  # Admission off unless MIN_FPS asks (both builds have the flag since 2026-12-02).
  extra="--min-session-fps ${MIN_FPS:-0} $extra"
  "$cv/$build/cinevol-server" --listen 127.0.0.1:0 --port-file "$port_file" --backend cuda --volume "$volume" \
    --max-sessions 256 --max-sessions-per-principal 256 --max-total-pixels 2000000000 \
    --max-streams-per-connection 1024 $extra \
    > "$logs/server-$tag.log" 2>&1 &
  local server=$!
  wait_for_port "$port_file" $server 30 "$logs/server-$tag.log"
  nvidia-smi --query-gpu=utilization.gpu,memory.used --format=csv,noheader,nounits -lms 250 > "$logs/smi-$tag.txt" &
  local smi=$! cpu0
  cpu0=$(cpu_seconds $server)
  local start=$SECONDS
  local what=(--width "$w" --height "$h" --spp "${SPP:-2}" --denoiser "${DENOISER:-wrls}" --scene "$scene")
  [ -n "${SCRIPT:-}" ] && what=(--script "$SCRIPT")
  # CLIENTS loadtest processes at once, each with its share of the sessions.
  local clients=${CLIENTS:-1} c pids=() rc=0
  for c in $(seq "$clients"); do
    "$cv/bin/cinevol" loadtest --server "127.0.0.1:$(cat "$port_file")" --sessions $((n / clients)) \
      --seconds "$seconds" "${what[@]}" --json "$@" > "$logs/loadtest-$tag-$c.json" 2> "$logs/loadtest-$tag-$c.err" &
    pids+=($!)
  done
  for c in "${pids[@]}"; do wait "$c" || rc=$?; done
  local elapsed=$((SECONDS - start)) cpu1
  cpu1=$(cpu_seconds $server)
  kill $smi
  kill -TERM $server
  wait $server
  python3 - "$logs/smi-$tag.txt" "$label" "$build" "$w" "$h" "$cpu0" "$cpu1" "$elapsed" "$rc" \
    "$logs"/loadtest-$tag-*.json >> "$table" <<'EOF'
import json, sys
smi, label, build, w, h, cpu0, cpu1, elapsed, rc = sys.argv[1:10]
try:
    runs = [json.load(open(path)) for path in sys.argv[10:]]
except Exception as e:
    print(f"| {label} | {build} | ? | {w}x{h} | loadtest failed (rc {rc}): {e} |"); sys.exit()
# With several clients: their sessions together, the worst client's latencies, the mean of their stages.
o = runs[0]["overall"]
for r in runs[1:]:
    for k in o["latency_ms"]: o["latency_ms"][k] = max(o["latency_ms"][k], r["overall"]["latency_ms"][k])
    o["dropped"] += r["overall"]["dropped"]
    for k, v in r["overall"]["errors"].items(): o["errors"][k] = o["errors"].get(k, 0) + v
s = {k: sum(r["overall"]["stage_ms"][k] for r in runs) / len(runs) for k in o["stage_ms"]}
# Sessions that streamed (an error at the end, e.g. a close past its deadline,
# does not undo their frames); refused ones count apart.
sessions = [p for r in runs for p in r["per_session"]]
served = [p for p in sessions if p["frames"] > 0]
fps = [p["fps"] for p in served]
util = [l.split(",") for l in open(smi) if l.strip()]
busy = [float(u) for u, m in util if float(u) > 0]
mem = max((float(m) for u, m in util), default=0)
errors = ", ".join(f"{k} {v}" for k, v in o["errors"].items()) or "-"
cores = (float(cpu1) - float(cpu0)) / max(float(elapsed), 1)
each = f"{sum(fps)/len(fps):.1f} ({min(fps):.1f})" if fps else "-"
print(f"| {label} | {build} | {len(sessions)} ({len(served)} served) | {w}x{h} | {each} "
      f"| {sum(fps):.0f} | {o['latency_ms']['p50']:.1f} / {o['latency_ms']['p95']:.1f} / {o['latency_ms']['p99']:.1f} | render {s['render']:.2f}, "
      f"denoise {s['denoise']:.2f}, display {s['tonemap']:.2f}, encode {s['encode']:.2f}, queue {s['queue']:.2f} "
      f"| {sum(busy)/max(len(busy),1):.0f}% | {mem:.0f} | {cores:.1f} | {o['dropped']} | {errors} |")
EOF
  echo "loadtest $tag rc=$rc"
}

table_header() {
  { echo; echo "### $1 ($(gpu_name), $(date -u +%F))"; echo
    echo "| run | build | sessions | size | fps each (min) | frames/s | p50 / p95 / p99 ms | stages ms | GPU busy | GPU MiB | server cores | dropped | errors |"
    echo "|---|---|---|---|---|---|---|---|---|---|---|---|---|"; } >> "$table"
}

step_tests() {
  "$cv/bin/cinevol_tests" --gtest_filter="${TESTS:-*Cuda*:*Nvjpeg*:*JpegIntervals*:FramePipeline.*:VolumeCache.*}" \
    > "$logs/gpu-tests.log" 2>&1
  echo "tests rc=$?: $(grep -E '^\[  (PASSED|FAILED) ' "$logs/gpu-tests.log" | tr '\n' ' ')" | tee -a "$table"
  grep -E '^\[  FAILED  \]' "$logs/gpu-tests.log" | head -20 >> "$table"
}

step_encode() {
  for build in bin bin-before; do
    "$cv/$build/cinevol-bench" encode --scene "$scene" --volume "$volume" --backend cuda \
      --jpeg-encoder "${JPEG_ENCODER:-auto}" --frames 100 --warmup 10 --out "$logs/encode-$build.md" \
      > "$logs/encode-$build.log" 2>&1
    echo "encode bench $build rc=$?"
  done
  cat "$logs/encode-bin.md" >> "$table"
}

step_pair() {
  table_header "Both builds alternating, 1280x720"
  for round in $(seq "${PAIR_ROUNDS:-1}"); do
    for n in ${PAIR_SESSIONS:-1 32 64}; do
      for build in bin-before bin; do loadtest "pair${PAIR_EXTRA:+-i}" "$build" "$n" 1280 720 ${PAIR_EXTRA:-}; done
    done
  done
}

step_sweep() {
  table_header "Sessions added, this build, 1280x720"
  for n in ${SWEEP:-1 8 16 32 48 64 96 128}; do loadtest sweep bin "$n" 1280 720; done
  for n in ${SWEEP_INTERACTIVE:-64 128}; do loadtest interactive33 bin "$n" 1280 720 --interactive-frame-ms 33; done
}

step_big() {
  table_header "One large session, both builds alternating"
  for run in $(seq "${BIG_RUNS:-2}"); do
    for build in bin-before bin; do
      loadtest big "$build" 1 3840 2160
      loadtest big "$build" 1 2560 1440
    done
    # A reading monitor whose moving frames render smaller to keep its budget.
    [ -n "${BIG_INTERACTIVE_MS:-}" ] &&
      loadtest "big-i$BIG_INTERACTIVE_MS" bin 1 3840 2160 --interactive-frame-ms "$BIG_INTERACTIVE_MS"
  done
}

step_admission() {
  table_header "Admission (--min-session-fps 30): sessions arriving over ${RAMP:-8} s, each ${ADMIT_SECONDS:-$seconds} s"
  local saved=$seconds
  seconds=${ADMIT_SECONDS:-$seconds}
  MIN_FPS=30 loadtest admission bin "${ADMIT_SESSIONS:-64}" 1280 720 --ramp-seconds "${RAMP:-8}"
  seconds=$saved
}

step_cpujpeg() {
  table_header "This build with the CPU's JPEG encoder"
  for n in ${CPUJPEG_SESSIONS:-1 64}; do
    SERVER_EXTRA="${SERVER_EXTRA:-} --jpeg-encoder cpu" loadtest cpu-jpeg bin "$n" 1280 720
  done
}

step_wait() {
  table_header "How render threads wait for the GPU (--gpu-wait), this build"
  for wait in ${WAITS:-auto block yield}; do
    local saved=${SERVER_EXTRA:-}
    SERVER_EXTRA="$saved --gpu-wait $wait"
    for n in ${WAIT_SESSIONS:-1 128}; do loadtest "wait-$wait" bin "$n" 1280 720; done
    for n in ${WAIT_INTERACTIVE:-128}; do loadtest "wait-$wait-i33" bin "$n" 1280 720 --interactive-frame-ms 33; done
    SERVER_EXTRA=$saved
  done
}

step_stretch() {
  table_header "Interactive frames upsampled by the server or stretched by the client, this build"
  for run in $(seq "${STRETCH_RUNS:-2}"); do
    for n in ${STRETCH_SESSIONS:-64 96 128}; do
      loadtest i33-upsampled bin "$n" 1280 720 --interactive-frame-ms 33 --server-upsamples
      loadtest i33-stretched bin "$n" 1280 720 --interactive-frame-ms 33
    done
  done
}

# script_runs LABEL SCRIPT RUNS SESSIONS BUILDS [LOADTEST FLAGS...]: loadtests of
# SCRIPT (its viewport 1280x720) for each count in SESSIONS, the BUILDS alternating.
script_runs() {
  local label=$1 script=$2 runs=$3 sessions=$4 builds=$5
  shift 5
  for run in $(seq "$runs"); do
    for n in $sessions; do
      for build in $builds; do SCRIPT=$script loadtest "$label" "$build" "$n" 1280 720 "$@"; done
    done
  done
}

step_stopgo() {
  table_header "Views that stop and go (bench/scenes/stop-and-go.jsonl), both builds alternating"
  script_runs stopgo "$cv/scenes/stop-and-go.jsonl" "${STOPGO_RUNS:-2}" "${STOPGO_SESSIONS:-32 64}" \
    "${STOPGO_BUILDS:-bin-before bin}" --ramp-seconds 1.6
}

step_tfdrag() {
  table_header "Transfer functions dragged (bench/scenes/tf-drag.jsonl), both builds alternating"
  script_runs tfdrag "$cv/scenes/tf-drag.jsonl" "${TFDRAG_RUNS:-2}" "${TFDRAG_SESSIONS:-32 64}" "bin-before bin"
}

step_sizes() {
  table_header "This build's sessions at each size (${DENOISER:-wrls}, ${SIZES_FLAGS:-no loadtest flags}; server: ${SERVER_EXTRA:-defaults})"
  for size in ${SIZES:-1280x720 640x360 320x180}; do
    # shellcheck disable=SC2086 # SIZES_FLAGS: several flags
    loadtest sizes bin "${SIZES_SESSIONS:-128}" "${size%x*}" "${size#*x}" ${SIZES_FLAGS:-}
  done
}

step_kernels() {
  local size=${KERNELS_SIZE:-640x360} port_file=$cv/port-kernels ncu=${NCU:-$(command -v ncu || echo /usr/local/cuda/bin/ncu)}
  local csv=$logs/kernels-$size.csv
  # Nsight Compute replays each kernel alone at its own clocks: times a quarter longer than a loadtest's.
  "$ncu" --target-processes all --launch-skip "${KERNELS_SKIP:-150}" --launch-count "${KERNELS_COUNT:-200}" \
    --csv --page raw --metrics gpu__time_duration.sum,sm__cycles_active.avg,sm__cycles_elapsed.avg,\
sm__warps_active.avg.pct_of_peak_sustained_active,launch__grid_size,launch__block_size,launch__registers_per_thread \
    "$cv/bin/cinevol-server" --listen 127.0.0.1:0 --port-file "$port_file" --backend cuda --volume "$volume" \
    --min-session-fps 0 > "$csv" 2> "$logs/kernels-ncu.err" &
  local profiler=$!
  wait_for_port "$port_file" $profiler 60 "$logs/kernels-ncu.err"
  # Profiled launches are slow (about 0.3 s each): one session, long enough for them all.
  "$cv/bin/cinevol" loadtest --server "127.0.0.1:$(cat "$port_file")" --sessions 1 --seconds "${KERNELS_SECONDS:-100}" \
    --width "${size%x*}" --height "${size#*x}" --spp "${SPP:-2}" --denoiser "${DENOISER:-wrls}" --scene "$scene" --json \
    > "$logs/kernels-loadtest.json" 2> "$logs/kernels-loadtest.err"
  # The server (ncu's descendant, by its process id), so that ncu writes its report.
  local pid servers=()
  for pid in $(descendants $profiler); do [ "$(cat "/proc/$pid/comm" 2> /dev/null)" = cinevol-server ] && servers+=("$pid"); done
  kill -TERM "${servers[@]}" 2> /dev/null
  for _ in $(seq 600); do kill -0 $profiler 2> /dev/null || break; sleep 0.1; done
  kill -KILL $profiler "${servers[@]}" 2> /dev/null
  wait $profiler
  { echo; echo "### Kernels of one ${size} session, Nsight Compute ($(gpu_name), $(date -u +%F))"; echo
    python3 bench/kernel_table.py "$csv"; } >> "$table"
}

# Is the loadtest client part of what slows many sessions? CLIENTS_SESSIONS (8 128) full-size sessions from one
# client and from two, alternating, two rounds.
step_clients() {
  table_header "One loadtest client or two, this build, 1280x720"
  for round in 1 2; do
    for n in ${CLIENTS_SESSIONS:-8 128}; do
      for clients in 1 2; do CLIENTS=$clients loadtest "clients-$clients" bin "$n" 1280 720; done
    done
  done
}

step_memory() {
  for build in bin-before bin; do
    [ -x "$cv/$build/cinevol_tests" ] || continue
    "$cv/$build/cinevol_tests" --gtest_filter='VolumeCache.PrintsTheDeviceMemoryOfA720pSession' \
      > "$logs/memory-$build.log" 2>&1
    { echo; echo "Device memory, $build ($(gpu_name)):"; grep -iE 'MiB|session' "$logs/memory-$build.log" | head -12; } \
      >> "$table"
  done
}

step_render() {
  local round build
  echo >> "$table"
  for round in $(seq "${RENDER_ROUNDS:-2}"); do
    for build in bin-before bin ${EXTRA_BUILDS:-}; do
      echo "render, $build, round $round: $("$cv/$build/cinevol-bench" render --scene "$scene" --volume "$volume" \
        --backend cuda --width 1280 --height 720 --frames 40 --warmup 5 --default-only 2> "$logs/render-$build-$round.err" \
        | grep '^| default')" >> "$table"
    done
  done
}

step_identity() {
  local build b same differing
  for build in bin-before bin ${EXTRA_BUILDS:-}; do
    rm -rf "$cv/tradeoff-$build" "$cv/refine-$build.csv"
    "$cv/$build/cinevol-bench" tradeoff --dataset "ct=$scene,$volume" --width 640 --height 360 --reference-spp 64 \
      --frames-scale 0.3 --scenario orbit --scenario point-light --denoisers-only --backend cuda \
      --cache "$cv/tradeoff-cache" --out "$cv/tradeoff-$build" > "$logs/identity-$build.log" 2>&1
    echo "tradeoff $build rc=$?"
    # A still past the refinement's first error estimate (frame 16): its quality columns.
    "$cv/$build/cinevol-bench" refine --scene "$scene" --volume "$volume" --backend cuda --width 640 --height 360 \
      --reference-spp 256 --target-spp 96 --orbit-frames 2 --reference "$cv/refine-reference.exr" \
      --csv "$cv/refine-$build.csv" > "$logs/identity-refine-$build.log" 2>&1
    echo "refine $build rc=$?"
  done
  local a=$cv/tradeoff-bin-before
  for build in bin ${EXTRA_BUILDS:-}; do
    b=$cv/tradeoff-$build same=same
    diff <(cut -d, -f1-15 "$a/tradeoff.csv") <(cut -d, -f1-15 "$b/tradeoff.csv") > /dev/null || same=DIFFERENT
    differing=$(cd "$a/images" && find . -type f | while read -r f; do cmp -s "$f" "$b/images/$f" || echo "$f"; done | wc -l)
    { echo; echo "bin-before and $build, the study (quality columns, $(wc -l < "$b/tradeoff.csv") rows): $same;" \
        "images differing: $differing of $(find "$b/images" -type f | wc -l)"; } >> "$table"
    # Images that differ: by how much, wRLS and SVGF before / after (the study's 0.05 dB rule).
    [ "$same" = same ] || python3 bench/compare_tradeoff.py "$a/tradeoff.json" "$b/tradeoff.json" >> "$table"
    same=same
    diff <(cut -d, -f1-7,9,10,12,13 "$cv/refine-bin-before.csv") <(cut -d, -f1-7,9,10,12,13 "$cv/refine-$build.csv") \
      > /dev/null || same=DIFFERENT
    echo "bin-before and $build, the still (refine bench, quality columns, $(wc -l < "$cv/refine-$build.csv") rows): $same" \
      >> "$table"
  done
}

step_study() {
  local dataset spec build
  for dataset in ${STUDY_DATASETS:-ct-head-cthead mr-head phantom ct-aorta}; do
    case $dataset in
      ct-head-cthead) spec="$dataset=$scene,$volume" ;;
      mr-head) spec="$dataset=examples/mr-head.json,${STUDY_DATA:?carry the MR head}/MR.nii.gz" ;;
      phantom) spec="$dataset=examples/ct-bone.json,phantom:head" ;;
      ct-aorta) spec="$dataset=bench/scenes/ct-aorta-bone.json,${STUDY_DATA:?carry the aorta crop}/aorta_ct_cropped.nii.gz" ;;
      *) echo "unknown study data set $dataset"; return 1 ;;
    esac
    for build in bin-before bin ${EXTRA_BUILDS:-}; do
      rm -rf "$cv/study-$dataset-$build"
      "$cv/$build/cinevol-bench" tradeoff --dataset "$spec" --backend cuda --width 1280 --height 720 --frames-scale 0.5 \
        --reference-spp 256 --reference-bounces 4 --variants-only --cache "$cv/study-cache" \
        --out "$cv/study-$dataset-$build" > "$logs/study-$dataset-$build.log" 2>&1
      echo "study $dataset $build rc=$?"
      cp "$cv/study-$dataset-$build/tradeoff.json" "$out/study-$dataset-$build.json"
    done
    for build in bin ${EXTRA_BUILDS:-}; do
      { echo; echo "The study at 720p, $dataset, bin-before against $build:"
        python3 bench/compare_tradeoff.py "$out/study-$dataset-bin-before.json" "$out/study-$dataset-$build.json"; } >> "$table"
    done
  done
}

nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv,noheader | tee "$out/gpu.txt"
# Only a few files come back: the logs travel in one archive, also when a
# server that does not start (wait_for_port) stops the run.
trap 'tar -C "$logs" -cJf "$out/logs.tar.xz" . 2> /dev/null; cat "$table" 2> /dev/null' EXIT
for step in ${STEPS:-tests encode pair}; do "step_$step"; done
