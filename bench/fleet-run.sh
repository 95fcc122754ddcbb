#!/usr/bin/env bash
# Two cinevol-servers on loopback standing in for two pods (docs/deploy.md,
# "Routing"): `cinevol loadtest --server A,B` places its sessions by room,
# then, a third of the way through, server A is killed (SIGKILL) and its
# sessions must go on from B. Prints where sessions went, how long the move
# took and the load test's numbers. By default the CPU backend from build/ at
# 160x96, so it runs anywhere; on the GPU machine, with the bundle of
# bench/make-gpu-bundle.sh:
#   SESSIONS=8 SECONDS_PER_RUN=30 bash bench/fleet-run.sh [BIN_DIR]
#   BACKEND=cuda VOLUME=/tmp/cv/data/ct-head-cthead/DERIVED_CThead.nhdr WIDTH=1280 HEIGHT=720 \
#     bash bench/fleet-run.sh /tmp/cv/bin
set -euo pipefail
cd "$(dirname "$0")/.."
. scripts/wait-for-port.sh
build=${1:-build}
sessions=${SESSIONS:-8}
seconds=${SECONDS_PER_RUN:-30}
backend=${BACKEND:-cpu}
volume=${VOLUME:-phantom:head?size=64}
scratch=$(mktemp -d)
pids=()
cleanup() {  # KEEP=1 keeps the logs
  for pid in "${pids[@]}"; do kill "$pid" 2>/dev/null || true; done
  if [ -n "${KEEP:-}" ]; then echo "logs in $scratch" >&2; else rm -rf "$scratch"; fi
}
trap cleanup EXIT

start_server() {  # NAME: starts one; its address goes to $scratch/NAME.address
  "$build/cinevol-server" --listen 127.0.0.1:0 --port-file "$scratch/$1.port" --backend "$backend" \
    --volume "$volume" --max-sessions "$sessions" --max-sessions-per-principal "$sessions" \
    > "$scratch/$1.log" 2>&1 &
  pids+=($!)
  wait_for_port "$scratch/$1.port" "${pids[-1]}" 30 "$scratch/$1.log"
  echo "127.0.0.1:$(cat "$scratch/$1.port")" > "$scratch/$1.address"
}
start_server a
a_pid=${pids[0]}
start_server b
a=$(cat "$scratch/a.address")
b=$(cat "$scratch/b.address")

( sleep "$((seconds / 3))"; date '+%F %T.%3N' > "$scratch/killed"; kill -KILL "$a_pid" ) &
killer=$!
status=0
"$build/cinevol" loadtest --server "$a,$b" --sessions "$sessions" --seconds "$seconds" --width "${WIDTH:-160}" --height "${HEIGHT:-96}" \
  --json --out "$scratch/loadtest.json" > /dev/null || status=$?
wait "$killer" || true
python3 - "$scratch" "$a" "$b" <<'PY'
import datetime, json, re, sys
scratch, a, b = sys.argv[1:]
report = json.load(open(f"{scratch}/loadtest.json"))
rows, o = report["per_session"], report["overall"]
def created(log):  # when each session was created, from the server's log
    stamps = re.findall(r"^\[([^\]]+)\] \[info\] session \w+: created", open(f"{scratch}/{log}").read(), re.M)
    return [datetime.datetime.fromisoformat(s) for s in stamps]
killed = datetime.datetime.fromisoformat(open(f"{scratch}/killed").read().strip())
on_a, on_b = created("a.log"), created("b.log")
moved = [t for t in on_b if t > killed]
print(f"{len(rows)} sessions over A={a} and B={b}, {report['seconds']} s; A killed (SIGKILL) at {report['seconds'] // 3} s")
print(f"placed at the start: {len(on_a)} on A, {len(on_b) - len(moved)} on B")
if moved:
    print(f"re-created on B after the kill: {len(moved)}, "
          f"{(min(moved) - killed).total_seconds():.2f} to {(max(moved) - killed).total_seconds():.2f} s after it")
ended = {s: sum(r["server"] == s for r in rows) for s in (a, b)}
print(f"sessions ended on A: {ended[a]}, on B: {ended[b]}; errors: {o['errors'] or 'none'}")
print(f"frames {o['frames']}, fps per session mean {o['fps_mean']} (min {o['fps_min']}), "
      f"latency p50/p95/p99 ms {o['latency_ms']['p50']}/{o['latency_ms']['p95']}/{o['latency_ms']['p99']}")
PY
exit $status
