#!/usr/bin/env python3
"""Offline checks of the deployment (issue 23): every kustomize overlay renders
(`kubectl kustomize`), and the rendered objects, the Compose stack and the
Dockerfiles keep the properties docs/deploy.md promises. Exits 77 (ctest's
skip) when kubectl is absent, naming what is missing."""
import pathlib
import re
import shutil
import subprocess
import sys

import yaml

root = pathlib.Path(__file__).resolve().parents[2]
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
    for kind in ("StatefulSet", "Service", "ConfigMap", "PodDisruptionBudget", "NetworkPolicy"):
        check(kind in kinds, f"{name}: no {kind}")
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
            check(c.get("livenessProbe", {}).get("grpc", {}).get("port") == 50051, f"{name}: no gRPC liveness probe")
            check(c.get("readinessProbe", {}).get("grpc", {}).get("service") == "cinevol.v1.SessionService",
                  f"{name}: readiness must ask cinevol.v1.SessionService (room for a session)")
            mounts = {m["name"]: m for m in c.get("volumeMounts", [])}
            check(mounts.get("data", {}).get("readOnly") is True, f"{name}: data not mounted read-only")
            check(any("--auth-tokens" in a for a in c.get("args", [])), f"{name}: no --auth-tokens")
    for policy in (o for o in objects if o["kind"] == "NetworkPolicy"):
        check(policy["spec"]["podSelector"].get("matchLabels"), f"{name}: the NetworkPolicy selects every pod")


def check_dockerfiles():
    for dockerfile in sorted((root / "docker").glob("*.Dockerfile")):
        text = dockerfile.read_text()
        check("scripts/install-deps.sh" in text and "scripts/build.sh" in text,
              f"{dockerfile.name}: does not build with the README's scripts")
        final = text[text.rfind("\nFROM "):]
        check(re.search(r"^USER 10001$", final, re.M), f"{dockerfile.name}: the final stage runs as root")
        check("server" not in dockerfile.name or "HEALTHCHECK" in final, f"{dockerfile.name}: no HEALTHCHECK")


def check_compose():
    compose = root / "deploy" / "compose"
    for f in ("docker-compose.yml", "gpu.yml", "prometheus.yml"):
        yaml.safe_load((compose / f).read_text())
    targets = yaml.safe_load((compose / "prometheus.yml").read_text())["scrape_configs"][0]["static_configs"][0]
    check(targets["targets"] == ["cinevol:9464"], "prometheus.yml: does not scrape cinevol:9464")


def main():
    if not shutil.which("kubectl"):
        print("kubectl not found (kubectl kustomize renders the manifests); skipping")
        return 77
    for overlay in sorted((root / "deploy" / "kubernetes" / "overlays").iterdir()):
        check_overlay(overlay.name, render(overlay))
    check_dockerfiles()
    check_compose()
    if shutil.which("yamllint"):
        lint = subprocess.run(["yamllint", "-d", "{extends: relaxed, rules: {line-length: {max: 120}}}",
                               str(root / "deploy")], capture_output=True, text=True)
        check(lint.returncode == 0, f"yamllint:\n{lint.stdout}")
    for p in problems:
        print("FAIL:", p)
    print(f"{len(problems)} problem(s)")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
