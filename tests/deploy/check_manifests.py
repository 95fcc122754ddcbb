#!/usr/bin/env python3
"""Offline checks of the deployment (issue 23): the kustomize base and every
overlay render (`kubectl kustomize`), every rendered object is valid against the
Kubernetes schemas (tests/deploy/schema/validate.js, with the npm package
kubernetes-models pinned by tests/deploy/schema/package-lock.json), and the
rendered objects, the Compose stack and the Dockerfiles keep the properties
docs/deploy.md promises.

    check_manifests.py [--cache-dir DIR]

DIR is where `npm ci` installs the schema package, outside the source tree
(ctest passes one in the build tree; else $CINEVOL_DEPLOY_SCHEMA_CACHE, else a
folder in the system temp dir). The install is reused while package.json and
the lock file are unchanged, so only the first run needs the npm registry; a
failed install is a failure, not a skip. Exits 77 (ctest's skip) when kubectl,
node or npm is absent, naming what is missing (the other checks still run, and
a problem they find still fails)."""
import argparse
import hashlib
import json
import os
import pathlib
import re
import shutil
import subprocess
import sys
import tempfile

import yaml

root = pathlib.Path(__file__).resolve().parents[2]
schema_dir = root / "tests" / "deploy" / "schema"
schema_stamp = ".cinevol-deploy-schema.sha256"  # in the cache folder: the inputs of its npm ci
npm_ci_timeout = 240
problems = []


def check(ok, what):
    if not ok:
        problems.append(what)


def render(overlay):
    out = subprocess.run(["kubectl", "kustomize", str(overlay)], capture_output=True, text=True)
    check(out.returncode == 0, f"{overlay}: kubectl kustomize failed: {out.stderr.strip()}")
    return [d for d in yaml.safe_load_all(out.stdout) if d] if out.returncode == 0 else []


def check_overlay(name, objects):
    kinds = {o["kind"] for o in objects}
    for kind in ("StatefulSet", "Deployment", "Service", "ConfigMap", "PodDisruptionBudget", "NetworkPolicy"):
        check(kind in kinds, f"{name}: no {kind}")
    check_web(name, objects)
    config = next((o for o in objects if o["kind"] == "ConfigMap"), {})
    drain = int(re.search(r"drain-seconds\s*=\s*(\d+)", config.get("data", {}).get("server.toml", "")).group(1))
    for sts in (o for o in objects if o["kind"] == "StatefulSet"):
        pod = sts["spec"]["template"]["spec"]
        check(pod.get("terminationGracePeriodSeconds", 30) > drain,
              f"{name}: terminationGracePeriodSeconds must exceed the server's drain-seconds ({drain})")
        check(pod["securityContext"].get("runAsNonRoot") is True, f"{name}: the pod may run as root")
        for c in pod["containers"]:
            sc = c.get("securityContext", {})
            check(sc.get("readOnlyRootFilesystem") is True, f"{name}/{c['name']}: root filesystem writable")
            check(sc.get("allowPrivilegeEscalation") is False, f"{name}/{c['name']}: privilege escalation allowed")
            check(c["resources"]["limits"].get("nvidia.com/gpu") == 1, f"{name}/{c['name']}: not one GPU per pod")
            tls = any(a.startswith("--tls-cert") for a in c.get("args", []))
            liveness, readiness = health_probe(c.get("livenessProbe", {}), tls), health_probe(c.get("readinessProbe", {}), tls)
            check(liveness == "", f"{name}: no gRPC health liveness probe the server can answer ({liveness})")
            check(readiness == "cinevol.v1.SessionService",
                  f"{name}: readiness must ask cinevol.v1.SessionService (room for a session) ({readiness})")
            mounts = {m["name"]: m for m in c.get("volumeMounts", [])}
            check(mounts.get("data", {}).get("readOnly") is True, f"{name}: data not mounted read-only")
            check(any("--auth-tokens" in a for a in c.get("args", [])), f"{name}: no --auth-tokens")
            check_advertised_address(name, sts, c, objects)
    for policy in (o for o in objects if o["kind"] == "NetworkPolicy"):
        check(policy["spec"]["podSelector"].get("matchLabels"), f"{name}: the NetworkPolicy selects every pod")


def health_probe(probe, tls):
    """The gRPC health service a probe asks of port 50051, or why it cannot: the kubelet's own
    gRPC probe speaks plaintext, so a server with --tls-cert needs `cinevol health` over TLS."""
    if "grpc" in probe:
        if tls:
            return "a gRPC probe, which speaks plaintext to a TLS-only port"
        return probe["grpc"].get("service", "") if probe["grpc"].get("port") == 50051 else "another port"
    command = " ".join(probe.get("exec", {}).get("command", []))
    m = re.search(r"/cinevol health .*:50051\S*(.*)", command)
    if not m:
        return "no probe"
    if tls and "--tls-ca" not in command:
        return "`cinevol health` without --tls-ca"
    service = re.search(r"--service (\S+)", m.group(0))
    return service.group(1) if service else ""


def check_web(name, objects):
    """cinevol-web (docs/web.md): TLS towards the browser and the server, sessions routed only to the server pods."""
    web = next((o for o in objects if o["kind"] == "Deployment" and o["metadata"]["name"] == "cinevol-web"), None)
    check(web is not None, f"{name}: no cinevol-web Deployment")
    if web is None:
        return
    pod = web["spec"]["template"]["spec"]
    args = " ".join(pod["containers"][0]["args"])
    for flag in ("--tls-cert=", "--server-tls-ca=", "--session-hosts=.cinevol-server-pods."):
        check(flag in args, f"{name}: cinevol-web runs without {flag}")
    # Every host an Ingress sends to cinevol-web must be one it answers (it refuses others: DNS rebinding).
    allowed_hosts = [a.split("=", 1)[1].split(",") for a in pod["containers"][0]["args"]
                     if a.startswith("--allowed-hosts=")]
    allowed_hosts = [h for hosts in allowed_hosts for h in hosts]
    for ingress in (o for o in objects if o["kind"] == "Ingress"):
        for rule in ingress["spec"].get("rules", []):
            to_web = any(p["backend"]["service"]["name"] == "cinevol-web" for p in rule["http"]["paths"])
            check(not to_web or rule["host"] in allowed_hosts,
                  f"{name}: cinevol-web would refuse the Ingress's host {rule['host']} (--allowed-hosts)")
    check(pod["securityContext"].get("runAsNonRoot") is True, f"{name}: cinevol-web may run as root")
    check(pod["containers"][0]["securityContext"].get("readOnlyRootFilesystem") is True,
          f"{name}: cinevol-web's file system is writable")
    allowed = [p for p in objects if p["kind"] == "NetworkPolicy"
               and p["spec"]["podSelector"]["matchLabels"].get("app.kubernetes.io/name") == "cinevol-server"
               and any(f.get("podSelector", {}).get("matchLabels", {}).get("app.kubernetes.io/name") == "cinevol-web"
                       for rule in p["spec"].get("ingress", []) for f in rule.get("from", []))]
    check(allowed, f"{name}: no NetworkPolicy lets cinevol-web reach the server pods")


def check_advertised_address(name, sts, container, objects):
    """Each pod answers CreateSession with its own name (docs/deploy.md,
    "Routing"), and every pod is reachable by it: in the cluster through the
    headless Service, outside through an Ingress host of its own."""
    advertise = next((a.split("=", 1)[1] for a in container.get("args", []) if a.startswith("--advertise-address=")), "")
    check(advertise.startswith("$(POD_NAME)."), f"{name}: pods do not advertise their own name ({advertise!r})")
    env = {e["name"]: e.get("valueFrom", {}).get("fieldRef", {}).get("fieldPath") for e in container.get("env", [])}
    check(env.get("POD_NAME") == "metadata.name", f"{name}: POD_NAME is not the pod's name")
    pods = [f"{sts['metadata']['name']}-{n}" for n in range(sts["spec"].get("replicas", 1))]
    host = advertise.split(":")[0]
    if host.endswith(".svc"):
        check(host.split(".")[1] == sts["spec"]["serviceName"], f"{name}: advertised through another Service than the "
                                                                 "StatefulSet's headless one")
        return
    selected = {o["spec"].get("selector", {}).get("statefulset.kubernetes.io/pod-name") for o in objects
                if o["kind"] == "Service"}
    hosts = {r.get("host") for o in objects if o["kind"] == "Ingress" for r in o["spec"].get("rules", [])}
    for pod in pods:
        check(pod in selected, f"{name}: no Service for pod {pod}, which advertises {host}")
        check(host.replace("$(POD_NAME)", pod) in hosts, f"{name}: no Ingress host for pod {pod}")


def install_schema_package(cache):
    """`npm ci` of tests/deploy/schema into `cache`, unless the stamp there says
    this very package.json and lock are installed. Returns the folder, or None
    with a problem recorded."""
    inputs = b"".join((schema_dir / f).read_bytes() + b"\0" for f in ("package.json", "package-lock.json"))
    digest = hashlib.sha256(inputs).hexdigest()
    stamp = cache / schema_stamp
    if stamp.is_file() and stamp.read_text().strip() == digest and (cache / "node_modules" / "kubernetes-models").is_dir():
        return cache
    if cache.exists() and any(cache.iterdir()) and not stamp.is_file():
        check(False, f"schema: refusing to replace {cache}: not empty, and not an install of this check's")
        return None
    cache.parent.mkdir(parents=True, exist_ok=True)
    staging = pathlib.Path(tempfile.mkdtemp(prefix=cache.name + ".installing-", dir=cache.parent))
    try:
        for f in ("package.json", "package-lock.json"):
            shutil.copy2(schema_dir / f, staging / f)
        print(f"installing the schema package (npm ci of {schema_dir.relative_to(root)}) into {cache}", flush=True)
        # --prefer-offline: the lock pins every version with its integrity hash,
        # so npm's cache may answer without asking the registry.
        cmd = ["npm", "ci", "--no-audit", "--no-fund", "--prefer-offline", "--ignore-scripts", "--loglevel=error"]
        try:
            out = subprocess.run(cmd, cwd=staging, capture_output=True, text=True, timeout=npm_ci_timeout,
                                 env={**os.environ, "npm_config_update_notifier": "false"})
            said = [line for line in (out.stderr or out.stdout).splitlines() if not re.match(r"npm error\s+at ", line)]
            failure = None if out.returncode == 0 else f"npm ci exited {out.returncode}:\n" + "\n".join(said[-20:])
        except subprocess.TimeoutExpired:
            failure = f"npm ci did not finish in {npm_ci_timeout} s"
        if failure:
            check(False, "schema: could not install the schema package kubernetes-models "
                         f"(tests/deploy/schema/package-lock.json) into {cache}; is the npm registry reachable? "
                         f"{failure}")
            return None
        (staging / schema_stamp).write_text(digest + "\n")
        if cache.exists():
            shutil.rmtree(cache)
        staging.rename(cache)
        return cache
    finally:
        shutil.rmtree(staging, ignore_errors=True)


def validate_schema(name, objects, modules):
    out = subprocess.run(["node", str(schema_dir / "validate.js"), "--modules", str(modules), "--label", name, "-"],
                         input=json.dumps(objects, default=str), capture_output=True, text=True, timeout=120)
    found = [line for line in out.stdout.splitlines() if line.strip()]
    if out.returncode == 1 and found:
        problems.extend(f"schema: {line}" for line in found)
    else:
        check(out.returncode == 0, f"schema: {name}: validate.js failed (exit {out.returncode}): "
                                   f"{(out.stderr or out.stdout).strip()}")


def check_dockerfiles():
    for dockerfile in sorted((root / "docker").glob("*.Dockerfile")):
        text = dockerfile.read_text()
        check("scripts/install-deps.sh" in text and "scripts/build.sh" in text,
              f"{dockerfile.name}: does not build with the README's scripts")
        final = text[text.rfind("\nFROM "):]
        check(re.search(r"^USER 10001$", final, re.M), f"{dockerfile.name}: the final stage runs as root")
        check("server" not in dockerfile.name or "HEALTHCHECK" in final, f"{dockerfile.name}: no HEALTHCHECK")
        check("server" not in dockerfile.name or "build/cinevol-reader" in text,
              f"{dockerfile.name}: does not ship cinevol-reader, which reads every file the server loads")


def check_compose():
    compose = root / "deploy" / "compose"
    for f in ("docker-compose.yml", "gpu.yml", "prometheus.yml"):
        yaml.safe_load((compose / f).read_text())
    targets = yaml.safe_load((compose / "prometheus.yml").read_text())["scrape_configs"][0]["static_configs"][0]
    check(targets["targets"] == ["cinevol:9464"], "prometheus.yml: does not scrape cinevol:9464")


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--cache-dir", type=pathlib.Path,
                        default=os.environ.get("CINEVOL_DEPLOY_SCHEMA_CACHE") or
                        pathlib.Path(tempfile.gettempdir()) / f"cinevol-deploy-schema-{os.getuid()}",
                        help="where npm ci installs the schema package (outside the source tree)")
    args = parser.parse_args()
    if not shutil.which("kubectl"):
        print("kubectl not found (kubectl kustomize renders the manifests); skipping")
        return 77
    kubernetes = root / "deploy" / "kubernetes"
    rendered = {"base": render(kubernetes / "base")}
    for overlay in sorted((kubernetes / "overlays").iterdir()):
        rendered[overlay.name] = render(overlay)
    missing = [tool for tool in ("node", "npm") if not shutil.which(tool)]
    if not missing:
        modules = install_schema_package(args.cache_dir.resolve())
        for name, objects in rendered.items():
            if modules and objects:
                validate_schema(name, objects, modules)
        if modules:
            print(f"schema: checked {sum(map(len, rendered.values()))} objects ({', '.join(rendered)})")
    for name, objects in rendered.items():
        if name == "base":
            continue
        try:
            check_overlay(name, objects)
        except (KeyError, TypeError, AttributeError, ValueError) as e:  # a field missing or of the wrong type
            check(False, f"{name}: the checks of its promises stopped at {type(e).__name__}: {e}")
    check_dockerfiles()
    check_compose()
    if shutil.which("yamllint"):
        lint = subprocess.run(["yamllint", "-d", "{extends: relaxed, rules: {line-length: {max: 120}}}",
                               str(root / "deploy")], capture_output=True, text=True)
        check(lint.returncode == 0, f"yamllint:\n{lint.stdout}")
    for p in problems:
        print("FAIL:", p)
    print(f"{len(problems)} problem(s)")
    if not problems and missing:
        print(f"{' and '.join(missing)} not found (the schema validation of the rendered objects needs them); skipping")
        return 77
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
