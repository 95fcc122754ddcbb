#!/usr/bin/env bash
# The production Kubernetes overlay played as pods with `podman kube play`: rendered as the
# offline check renders it (kubectl kustomize), changed only where one host without a cluster
# or a GPU must (tests/containers/kube_for_podman.py: the StatefulSet's pods, the CPU image,
# the operator's Secrets and claim as folders made here), started on a network of its own, and
# every probe of every pod asked as the kubelet asks it: exec probes inside the container,
# HTTPS probes without checking the certificate, gRPC probes in plaintext. Services, Ingresses,
# NetworkPolicies and the PodDisruptionBudget are not played (podman runs none of them): the
# offline check (Deployment.ManifestsRenderAndKeepTheirPromises) keeps them. Then the pods and
# the network are removed by name.
#
#   tests/containers/kube_play_test.sh BUILD_DIR
#
# $CINEVOL_KUBE_SERVER_PODS: how many of the StatefulSet's pods to start (2). Without podman the
# test fails under CI (CI=true) and is skipped (77) elsewhere, saying so.
set -euo pipefail
[ $# -eq 1 ] || { echo "usage: $0 BUILD_DIR" >&2; exit 2; }
build_dir=$(realpath "$1")
root=$(cd "$(dirname "$0")/../.." && pwd)
work="$build_dir/kube-play-test"
network="cinevol-kube-$$"
replicas=${CINEVOL_KUBE_SERVER_PODS:-2}
[[ "$replicas" =~ ^[1-8]$ ]] || { echo "CINEVOL_KUBE_SERVER_PODS must be 1 to 8" >&2; exit 2; }
t0=$SECONDS
log() { printf '[%4d s] %s\n' "$((SECONDS - t0))" "$*"; }
fail() { log "FAIL: $*"; exit 1; }
# The ConfigMaps' names in $play (podman makes a volume of each).
configmaps() {
  [ -f "$play" ] && python3 -c 'import sys, yaml
print(" ".join(o["metadata"]["name"] for o in yaml.safe_load_all(open(sys.argv[1])) if o and o["kind"] == "ConfigMap"))' "$play"
}

missing=()
for tool in podman kubectl catatonit openssl curl python3; do
  command -v "$tool" > /dev/null || [ -x "/usr/libexec/podman/$tool" ] || missing+=("$tool")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "kube play: ${missing[*]} not found (scripts/install-deps.sh installs podman and catatonit)"
  [ "${CI:-}" = true ] && { echo "FAIL: CI must run the containers check"; exit 1; }
  echo "skipping: this machine cannot play the manifests"
  exit 77
fi

# A run killed before its cleanup (a ctest timeout kills outright) leaves its pods, whose names are fixed.
if [ -f "$work/play.yaml" ]; then
  timeout 120 podman kube play --down "$work/play.yaml" > /dev/null 2>&1 || true
  for volume in $(play=$work/play.yaml configmaps); do podman volume rm -f "$volume" > /dev/null 2>&1; done
  for stale in $(podman network ls --format '{{.Name}}' | grep -E '^cinevol-kube-[0-9]+$'); do
    kill -0 "${stale#cinevol-kube-}" 2> /dev/null || podman network rm -f "$stale" > /dev/null 2>&1
  done
fi
rm -rf "$work"
mkdir -p "$work"
play="$work/play.yaml"
pods=()
cleanup() {
  local status=$?
  set +e
  for pod in "${pods[@]}"; do
    podman logs "$pod-$(container_of "$pod")" > "$work/log-$pod.txt" 2>&1
  done
  [ -f "$play" ] && timeout 120 podman kube play --down "$play" > "$work/down.log" 2>&1
  for pod in "${pods[@]}"; do podman pod rm -f -t 5 "$pod" > /dev/null 2>&1; done
  # The ConfigMap's volume, which podman 4.3 leaves after --down.
  for volume in $(configmaps); do podman volume rm -f "$volume" > /dev/null 2>&1; done
  podman network rm -f "$network" > /dev/null 2>&1
  for pod in "${pods[@]}"; do
    podman pod exists "$pod" && { echo "FAIL: pod $pod was left behind"; status=1; }
  done
  podman network exists "$network" && { echo "FAIL: network $network was left behind"; status=1; }
  for volume in $(configmaps); do
    podman volume exists "$volume" && { echo "FAIL: volume $volume was left behind"; status=1; }
  done
  exit $status
}
trap cleanup EXIT
container_of() { case "$1" in cinevol-web-*) echo cinevol-web ;; *) echo server ;; esac; }

log "images (scripts/images.sh --fast server-cpu web)"
CINEVOL_BUILD_DIR="$build_dir" "$root/scripts/images.sh" --fast server-cpu web 2>&1 | tail -3

# --- The operator's Secrets, made here: a CA, the servers' certificate for their names, the page's, a token.
umask 022
secrets="$work/secrets"
mkdir -p "$secrets/cinevol-tokens" "$secrets/cinevol-tls" "$secrets/cinevol-web-tls" "$work/data"
tls="$secrets/cinevol-tls"
ec=(-newkey ec -pkeyopt ec_paramgen_curve:prime256v1 -nodes)
openssl req -x509 "${ec[@]}" -days 2 -subj /CN=cinevol-test-ca -keyout "$work/ca.key" -out "$tls/ca.crt" 2> /dev/null
openssl req "${ec[@]}" -subj /CN=cinevol-server -keyout "$tls/tls.key" -out "$work/server.csr" 2> /dev/null
openssl x509 -req -in "$work/server.csr" -CA "$tls/ca.crt" -CAkey "$work/ca.key" -CAcreateserial -days 2 \
  -extfile <(echo "subjectAltName=DNS:*.cinevol-server-pods.cinevol.svc,DNS:cinevol-server.cinevol.svc,DNS:*.cinevol.example.org") \
  -out "$tls/tls.crt" 2> /dev/null
openssl req -x509 "${ec[@]}" -days 2 -subj /CN=viewer.cinevol.example.org -keyout "$secrets/cinevol-web-tls/tls.key" \
  -out "$secrets/cinevol-web-tls/tls.crt" 2> /dev/null
echo "t-$(openssl rand -hex 24) alice operator" > "$secrets/cinevol-tokens/tokens"
chmod 644 "$secrets"/*/*

# --- The production overlay, rendered and made playable.
kubectl kustomize "$root/deploy/kubernetes/overlays/production" > "$work/rendered.yaml"
ports=$(python3 -c 'import socket
socks = [socket.socket() for _ in range(2 + 2 * int(__import__("sys").argv[1]))]
for s in socks: s.bind(("127.0.0.1", 0))
print(",".join(str(s.getsockname()[1]) for s in socks))' "$replicas")
python3 "$root/tests/containers/kube_for_podman.py" "$work/rendered.yaml" --server-image localhost/cinevol-server:cpu \
  --web-image localhost/cinevol-web:latest --replicas "$replicas" --secrets "$secrets" --data "$work/data" \
  --ports "$ports" --probes "$work/probes.jsonl" > "$play" 2> "$work/left-out.txt"
log "$(cat "$work/left-out.txt")"
mapfile -t pods < <(python3 -c 'import json,sys
seen = []
for line in open(sys.argv[1]):
    p = json.loads(line)["pod"]
    if p not in seen: seen.append(p)
print("\n".join(seen))' "$work/probes.jsonl")

podman network create "$network" > /dev/null
log "podman kube play (${pods[*]})"
start=$SECONDS
timeout 180 podman kube play --network "$network" "$play" > "$work/play.log" 2>&1 || { tail -5 "$work/play.log"; fail "podman kube play"; }

# --- Every probe, asked as the kubelet asks it, within the time the manifest gives it.
ask() {  # ask PROBE_JSON: exit 0 when the probe passes once
  CINEVOL_CLI="$build_dir/cinevol" python3 - "$1" <<'EOF'
import json, os, subprocess, sys
p = json.loads(sys.argv[1])
container = f"{p['pod']}-{p['container']}"
if p["kind"] == "exec":
    cmd = ["podman", "exec", container, *p["command"]]
elif p["kind"] == "httpGet":  # the kubelet does not check an HTTPS probe's certificate
    cmd = ["curl", "-sf", "-k" if p.get("scheme") == "HTTPS" else "-s", "--max-time", "5",
           f"{p.get('scheme', 'HTTP').lower()}://127.0.0.1:{p['hostPort']}{p.get('path', '/')}"]
elif p["kind"] == "grpc":  # the kubelet's gRPC probe: plaintext
    cmd = [os.environ["CINEVOL_CLI"], "health", "--server", f"127.0.0.1:{p['hostPort']}", "--connect-timeout", "2"]
    cmd += ["--service", p["service"]] if p.get("service") else []
else:
    sys.exit(f"a {p['kind']} probe")
sys.exit(subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, timeout=30).returncode)
EOF
}
while read -r probe; do
  what=$(python3 -c 'import json,sys; p=json.loads(sys.argv[1]); print(p["pod"], p["probe"], p["kind"], p.get("service",""))' "$probe")
  # The startup probe may take its whole allowance; the others must pass within theirs.
  allowance=$(python3 -c 'import json,sys; p=json.loads(sys.argv[1])
print(max(10, p.get("periodSeconds", 10) * p.get("failureThreshold", 3)) if p["probe"] == "startupProbe" else 30)' "$probe")
  end=$((SECONDS + allowance))
  until ask "$probe"; do
    [ $SECONDS -lt $end ] || fail "$what: did not pass within $allowance s"
    sleep 1
  done
  log "passes: $what"
done < <(python3 -c 'import json,sys
order = {"startupProbe": 0, "livenessProbe": 1, "readinessProbe": 2}
probes = [json.loads(l) for l in open(sys.argv[1])]
for p in sorted(probes, key=lambda p: order[p["probe"]]): print(json.dumps(p))' "$work/probes.jsonl")
log "every probe of ${#pods[@]} pods passes, $((SECONDS - start)) s after podman kube play"

# What the manifests asked before: the kubelet's own gRPC probe, in plaintext, which the TLS-only port refuses.
grpc_port=$(podman pod inspect cinevol-server-0 --format '{{json .InfraConfig.PortBindings}}' |
            python3 -c 'import json,sys; print(json.load(sys.stdin)["50051/tcp"][0]["HostPort"])')
if "$build_dir/cinevol" health --server "127.0.0.1:$grpc_port" --connect-timeout 2 > /dev/null 2>&1; then
  fail "the TLS port answered a plaintext gRPC health check: the exec probes' reason is gone (docs/deploy.md)"
fi
log "as expected, a plaintext gRPC probe (the kubelet's own) gets no answer from the TLS-only port"
