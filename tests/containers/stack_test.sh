#!/usr/bin/env bash
# The one-node stack (deploy/compose/docker-compose.yml) built and run for real with podman
# and podman-compose: scripts/images.sh --fast makes the images from the build tree's
# programs, the stack starts under a project name of its own on free loopback ports, and it
# is checked from outside: every service's health, and a session's first frame through
# cinevol-web (HTTPS, the Connect protocol). Then everything it started is removed by name.
#
#   tests/containers/stack_test.sh BUILD_DIR [--full] [--keep-images]
#
# --full adds the rest of docs/deploy.md's checks: Orthanc seeded with a DICOM series of the
# shared data ($CINEVOL_SHARED_DATA, /work/shared/data by default), searched and loaded
# through the server (`cinevol pacs`), the page's screenshot in Debian's chromium (from
# outside the stack), Prometheus' targets and rules through its HTTP API, a SIGTERM drain of
# the server while a session streams, the stack taken down and up again with Orthanc's data
# still there, and the idle stack's memory (podman stats). Artifacts and a summary go to
# BUILD_DIR/containers-test/.
#
# Without podman the test fails under CI (CI=true) and is skipped (77) elsewhere, saying so.
# Every wait is bounded; nothing listens beyond 127.0.0.1.
set -euo pipefail
[ $# -ge 1 ] || { echo "usage: $0 BUILD_DIR [--full]" >&2; exit 2; }
build_dir=$(realpath "$1"); shift
full=0
for a in "$@"; do
  case "$a" in --full) full=1 ;; *) echo "unknown argument $a" >&2; exit 2 ;; esac
done
root=$(cd "$(dirname "$0")/../.." && pwd)
compose_file="$root/deploy/compose/docker-compose.yml"
work="$build_dir/containers-test"
project="cinevol-test-$$"
shared_data=${CINEVOL_SHARED_DATA:-/work/shared/data}
t0=$SECONDS

log() { printf '[%4d s] %s\n' "$((SECONDS - t0))" "$*"; }
fail() { log "FAIL: $*"; exit 1; }

missing=()
for tool in podman podman-compose mmdebstrap runc node openssl curl python3 $([ "$full" = 1 ] && echo dcmodify); do
  command -v "$tool" > /dev/null || missing+=("$tool")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "containers: ${missing[*]} not found (scripts/install-deps.sh installs podman, podman-compose, mmdebstrap, runc)"
  [ "${CI:-}" = true ] && { echo "FAIL: CI must run the containers check"; exit 1; }
  echo "skipping: this machine cannot run containers"
  exit 77
fi

# A run killed before its cleanup (a ctest timeout kills outright) leaves its project: removed here,
# by the label podman-compose gives, when the process that named it is gone.
for stale in $(podman ps -a --format '{{index .Labels "io.podman.compose.project"}}' | grep -E '^cinevol-test-[0-9]+$' | sort -u); do
  kill -0 "${stale#cinevol-test-}" 2> /dev/null && continue
  echo "removing the stack $stale, left by a run that was killed"
  podman rm -f -t 5 $(podman ps -a -q --filter "label=io.podman.compose.project=$stale") > /dev/null
  podman volume rm -f "${stale}_orthanc-data" "${stale}_prometheus-data" > /dev/null 2>&1
  podman network rm -f "${stale}_default" > /dev/null 2>&1
done

rm -rf "$work"
mkdir -p "$work"
summary="$work/summary.txt"
: > "$summary"
note() { log "$*"; echo "$*" >> "$summary"; }

# --- Cleanup: the project's containers, pod, network and volumes, by name and by label; then a check that none is left.
cleanup() {
  local status=$?
  set +e
  if [ -n "${watcher:-}" ]; then kill "$watcher" 2> /dev/null; wait "$watcher" 2> /dev/null; fi
  local service
  for service in cinevol web orthanc prometheus; do
    podman logs "${project}_${service}_1" > "$work/log-$service.txt" 2>&1
  done
  (cd "$work" && timeout 120 podman-compose -p "$project" -f "$compose_file" down -t 30 > "$work/down.log" 2>&1)
  local ids
  ids=$(podman ps -a -q --filter "label=io.podman.compose.project=$project")
  [ -n "$ids" ] && podman rm -f -t 5 $ids > /dev/null
  for v in orthanc-data prometheus-data; do podman volume rm -f "${project}_$v" > /dev/null 2>&1; done
  podman network rm -f "${project}_default" > /dev/null 2>&1
  if [ -n "$(podman ps -a -q --filter "label=io.podman.compose.project=$project")" ] ||
     podman volume exists "${project}_orthanc-data" || podman network exists "${project}_default"; then
    echo "FAIL: the stack $project left containers, volumes or a network behind"
    status=1
  fi
  exit $status
}
trap cleanup EXIT

# --- Images, from the build tree (the fast path).
log "building the images (scripts/images.sh --fast)"
start=$SECONDS
CINEVOL_BUILD_DIR="$build_dir" "$root/scripts/images.sh" --fast server-cpu web orthanc prometheus 2>&1 | tail -6
note "images built (--fast, 4 images) in $((SECONDS - start)) s"

# --- Secrets: a token, the PACS's user, the page's certificate; readable by the containers' users.
umask 022
secrets="$work/secrets"
mkdir -p "$secrets/server" "$secrets/web" "$secrets/orthanc" "$work/data"
token="t-$(openssl rand -hex 24)"
echo "$token alice operator" > "$secrets/server/tokens"
orthanc_password="p-$(openssl rand -hex 16)"
echo "orthanc basic cinevol:$orthanc_password" > "$secrets/server/pacs.cred"
printf '{"RegisteredUsers": {"cinevol": "%s"}}\n' "$orthanc_password" > "$secrets/orthanc/users.json"
openssl req -x509 -newkey ec -pkeyopt ec_paramgen_curve:prime256v1 -nodes -days 2 -subj /CN=localhost \
  -addext "subjectAltName=IP:127.0.0.1,DNS:localhost" -keyout "$secrets/web/tls.key" -out "$secrets/web/tls.crt" 2> /dev/null
chmod 644 "$secrets"/*/*
if [ "$full" = 1 ]; then
  [ -d "$shared_data/mr-chest-dicom-seg3d" ] || fail "no shared data at $shared_data (CINEVOL_SHARED_DATA)"
fi

# Four free loopback ports (taken once; podman binds them moments later).
read -r grpc_port web_port orthanc_port prometheus_port < <(python3 - <<'EOF'
import socket
socks = [socket.socket() for _ in range(4)]
for s in socks:
    s.bind(("127.0.0.1", 0))
print(*(s.getsockname()[1] for s in socks))
EOF
)
export CINEVOL_BIND=127.0.0.1 CINEVOL_GRPC_PORT=$grpc_port CINEVOL_WEB_PORT=$web_port ORTHANC_PORT=$orthanc_port \
       PROMETHEUS_PORT=$prometheus_port CINEVOL_SECRETS=$secrets CINEVOL_DATA=$work/data
server="127.0.0.1:$grpc_port"
cli="$build_dir/cinevol"

compose() { (cd "$work" && timeout 180 podman-compose -p "$project" -f "$compose_file" "$@"); }

# Waits (bounded) until `cmd` succeeds: wait_for SECONDS WHAT CMD...
wait_for() {
  local seconds=$1 what=$2 end=$((SECONDS + $1)); shift 2
  until "$@" > /dev/null 2>&1; do
    [ $SECONDS -lt $end ] || fail "$what: not within $seconds s"
    sleep 1
  done
}
# The image's own HEALTHCHECK, run now (podman runs it on a timer only under systemd).
healthy() { podman healthcheck run "${project}_$1_1"; }
https_ok() { curl -sf --max-time 5 --cacert "$secrets/web/tls.crt" "https://127.0.0.1:$web_port$1" > /dev/null; }

stack_up() {
  compose up -d --no-build > "$work/up-$1.log" 2>&1 || { tail -20 "$work/up-$1.log"; fail "podman-compose up"; }
  wait_for 90 "the server's gRPC health (cinevol health)" "$cli" health --server "$server" --connect-timeout 2
  for service in cinevol web orthanc prometheus; do
    wait_for 60 "$service's HEALTHCHECK" healthy "$service"
  done
}

# --- Up, healthy, a first frame through the gateway.
log "starting the stack $project (podman-compose up)"
up_started=$SECONDS
stack_up first
note "stack up and every HEALTHCHECK passing $((SECONDS - up_started)) s after podman-compose up"
if [ "$full" = 1 ]; then  # the idle stack's memory: up, no session yet
  sleep 10
  podman stats --no-stream --format '{{.Name}} {{.MemUsage}} {{.CPUPerc}}' \
    "${project}_cinevol_1" "${project}_web_1" "${project}_orthanc_1" "${project}_prometheus_1" > "$work/stats.txt"
  note "idle: $(sed "s/^${project}_//" "$work/stats.txt" | tr '\n' ';')"
fi
wait_for 30 "cinevol-web's /healthz over HTTPS" https_ok /healthz
node "$root/tests/containers/watch_session.mjs" --url "https://127.0.0.1:$web_port" --ca "$secrets/web/tls.crt" \
  --token "$token" --volume phantom:head --out "$work/first-frame.jpg" --timeout 90 | tee "$work/first-frame.log"
note "first frame through cinevol-web $((SECONDS - up_started)) s after podman-compose up ($(wc -c < "$work/first-frame.jpg") bytes)"

if [ "$full" = 0 ]; then
  note "done in $((SECONDS - t0)) s"
  exit 0
fi

# --- Orthanc seeded from the shared data, searched and loaded through the server.
# The series has no Series Instance UID, which a PACS requires: copies are given one (DCMTK's dcmodify).
series="$shared_data/mr-chest-dicom-seg3d"
mkdir -p "$work/series"
count=0
for f in "$series"/*.dcm; do
  [ $((count += 1)) -le 200 ] || fail "more than 200 files in $series"
  cp "$f" "$work/series/"
done
series_uid="2.25.$(python3 -c 'import uuid; print(uuid.uuid4().int)')"
dcmodify -nb -i "(0020,000e)=$series_uid" "$work/series"/*.dcm || fail "dcmodify could not stamp the series"
for f in "$work/series"/*.dcm; do
  curl -sf --max-time 20 -u "cinevol:$orthanc_password" -H "Content-Type: application/dicom" \
    --data-binary "@$f" "http://127.0.0.1:$orthanc_port/instances" > /dev/null || fail "Orthanc refused $f"
done
note "Orthanc seeded with $count instances of $(basename "$series")"
"$cli" pacs list --server "$server" --token "$token" | tee "$work/pacs-list.txt"
"$cli" pacs search --server "$server" --token "$token" --pacs orthanc --modality MR --json > "$work/pacs-search.json"
study=$(python3 -c 'import json,sys; d=json.load(open(sys.argv[1])); print(d["studies"][0]["studyUid"])' \
        "$work/pacs-search.json") || fail "the PACS search found no study: $(head -c 400 "$work/pacs-search.json")"
start=$SECONDS
"$cli" pacs load --server "$server" --token "$token" --pacs orthanc --study "$study" --json > "$work/pacs-load.json"
volume=$(python3 -c 'import json,sys; d=json.load(open(sys.argv[1])); print(d.get("id") or d["volumeId"])' \
         "$work/pacs-load.json") || fail "the PACS load answered no volume: $(head -c 400 "$work/pacs-load.json")"
note "PACS: study $study found and loaded as $volume in $((SECONDS - start)) s"

# --- The page in chromium, from outside the stack, on the PACS's volume.
spki=$(openssl x509 -in "$secrets/web/tls.crt" -pubkey -noout | openssl pkey -pubin -outform der |
       openssl dgst -sha256 -binary | base64)
NODE_PATH="$root/web/node_modules" node "$root/tests/containers/screenshot.mjs" \
  --url "https://127.0.0.1:$web_port/?volume=$volume#token=$token" --spki "$spki" --out "$work/page.png" |
  tee "$work/screenshot.log"
note "the page's screenshot: $work/page.png"

# --- Prometheus: the server's target up, its metrics in, the alert rules loaded.
prom() { curl -sf --max-time 5 "http://127.0.0.1:$prometheus_port/api/v1/$1"; }
target_up() { prom targets | python3 -c 'import json,sys; t=json.load(sys.stdin)["data"]["activeTargets"]
sys.exit(0 if any(x["labels"]["job"]=="cinevol" and x["health"]=="up" for x in t) else 1)'; }
frames_scraped() { prom 'query?query=sum(cinevol_frames_sent_total)' | python3 -c 'import json,sys
r=json.load(sys.stdin)["data"]["result"]; sys.exit(0 if r and float(r[0]["value"][1]) > 0 else 1)'; }
wait_for 60 "Prometheus scraping cinevol:9464" target_up
wait_for 60 "cinevol_frames_sent_total in Prometheus" frames_scraped
prom rules > "$work/prometheus-rules.json"
rules=$(python3 -c 'import json,sys; g=json.load(open(sys.argv[1]))["data"]["groups"]
print(" ".join(r["name"] for x in g if x["name"]=="cinevol" for r in x["rules"]))' "$work/prometheus-rules.json")
[ -n "$rules" ] || fail "Prometheus has not loaded the cinevol rules"
note "Prometheus: target cinevol up, cinevol_frames_sent_total > 0, rules loaded: $rules"

# --- SIGTERM drain: a session streams through the gateway while the server is stopped.
node "$root/tests/containers/watch_session.mjs" --url "https://127.0.0.1:$web_port" --ca "$secrets/web/tls.crt" \
  --token "$token" --volume phantom:head --until-end --timeout 120 > "$work/drain-watch.log" 2>&1 &
watcher=$!
wait_for 60 "the watching session's first frame" grep -q READY "$work/drain-watch.log"
start=$SECONDS
podman stop -t 30 "${project}_cinevol_1" > /dev/null
stopped_in=$((SECONDS - start))
wait "$watcher" || { cat "$work/drain-watch.log"; fail "the watching session did not end cleanly on the drain"; }
watcher=
cat "$work/drain-watch.log"
podman logs --tail 8 "${project}_cinevol_1" > "$work/drain-server.log" 2>&1
exit_code=$(podman inspect --format '{{.State.ExitCode}}' "${project}_cinevol_1")
[ "$exit_code" = 0 ] || fail "the server exited $exit_code after SIGTERM (podman stop -t 30)"
note "drain: podman stop (SIGTERM) took $stopped_in s, the server exited 0; the stream: $(grep 'stream ended' "$work/drain-watch.log")"

# --- Down and up again (volumes kept): Orthanc still holds the study.
compose down -t 30 > "$work/down-keep.log" 2>&1 || fail "podman-compose down"
up_started=$SECONDS
stack_up second
"$cli" pacs search --server "$server" --token "$token" --pacs orthanc --modality MR --json > "$work/pacs-search-2.json"
grep -q "$study" "$work/pacs-search-2.json" || fail "after the restart Orthanc no longer holds study $study"
note "restart: stack up again in $((SECONDS - up_started)) s; Orthanc still holds study $study (volume orthanc-data)"
note "done in $((SECONDS - t0)) s"
