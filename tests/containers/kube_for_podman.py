#!/usr/bin/env python3
"""The rendered production overlay as `podman kube play` (podman 4.3) can run it, changed only
where a single host without a cluster or a GPU must:

- the StatefulSet becomes its pods, cinevol-server-0 .. -(N-1), as its controller would make them
  (the pod template, the pod's name and the statefulset.kubernetes.io/pod-name label); podman
  plays Pods and Deployments, not StatefulSets;
- the server image is the CPU one and the ConfigMap's `backend = "cuda"` is `"cpu"`; no
  nvidia.com/gpu;
- the Secrets and the PersistentVolumeClaim the overlay names but leaves to the operator
  (cinevol-tokens, cinevol-tls, cinevol-web-tls, cinevol-volumes) are hostPath folders the test
  makes; an emptyDir stays an emptyDir;
- the downward API's pod name and namespace are written in as values, and $(VAR) in the
  arguments expanded from them, as the kubelet does (podman 4.3 does neither);
- each server pod's own name under the headless Service resolves to itself (hostAliases), as
  the cluster's DNS would make it;
- each container port is published on 127.0.0.1 at a port given here (hostIP, hostPort), so that
  the probes can be asked from outside, as the kubelet asks them.

Services, Ingresses, NetworkPolicies and the PodDisruptionBudget are left out (podman runs none
of them); their names are printed on stderr. The probes (which podman 4.3 does not run) are
written to --probes FILE, one JSON object a line, with the host port each one asks, for the
test to ask them as the kubelet would.

    kube_for_podman.py RENDERED.yaml --server-image IMG --web-image IMG --replicas N \
        --secrets DIR --data DIR --ports P1,P2,... --probes FILE > play.yaml
"""
import argparse
import copy
import json
import sys

import yaml

RUNS = {"ConfigMap", "StatefulSet", "Deployment"}


def host_paths(volumes, secrets, data):
    """Secret and claim volumes as folders on this host: SECRETS/<secret name>, DATA."""
    out = []
    for v in volumes:
        v = dict(v)
        if "secret" in v:
            name = v.pop("secret")["secretName"]
            v["hostPath"] = {"path": f"{secrets}/{name}", "type": "Directory"}
        elif "persistentVolumeClaim" in v:
            v.pop("persistentVolumeClaim")
            v["hostPath"] = {"path": data, "type": "Directory"}
        elif "emptyDir" in v:
            v["emptyDir"] = {}  # podman 4.3 takes no sizeLimit
        out.append(v)
    return out


def downward_values(container, pod, namespace):
    """The downward API's fields as the values it would give: podman 4.3 fills in no metadata.namespace."""
    for e in container.get("env", []):
        field = e.get("valueFrom", {}).get("fieldRef", {}).get("fieldPath")
        if field in ("metadata.name", "metadata.namespace"):
            e.pop("valueFrom")
            e["value"] = pod if field == "metadata.name" else namespace


def expand_args(container):
    """$(VAR) in command and args from the container's env, as the kubelet expands them (podman 4.3 does not)."""
    env = {e["name"]: e["value"] for e in container.get("env", []) if "value" in e}
    for key in ("command", "args"):
        if key in container:
            out = []
            for arg in container[key]:
                for name, value in env.items():
                    arg = arg.replace(f"$({name})", value)
                out.append(arg)
            container[key] = out


def publish(container, ports, probes, pod):
    for p in container.get("ports", []):
        p["hostIP"] = "127.0.0.1"
        p["hostPort"] = ports.pop(0)
    by_name = {p.get("name"): p for p in container.get("ports", [])}
    by_number = {p["containerPort"]: p for p in container.get("ports", [])}
    for kind in ("startupProbe", "livenessProbe", "readinessProbe"):
        probe = container.pop(kind, None)  # podman 4.3 plays none of these probes: the test asks them
        if not probe:
            continue
        how = next(k for k in ("grpc", "httpGet", "tcpSocket", "exec") if k in probe)
        spec = dict(probe[how])
        port = spec.get("port")
        target = by_name.get(port) if isinstance(port, str) else by_number.get(port)
        spec["hostPort"] = target["hostPort"] if target else None
        for k in ("periodSeconds", "failureThreshold", "timeoutSeconds"):
            if k in probe:
                spec[k] = probe[k]
        probes.append({"pod": pod, "container": container["name"], "probe": kind, "kind": how, **spec})


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("rendered")
    ap.add_argument("--server-image", required=True)
    ap.add_argument("--web-image", required=True)
    ap.add_argument("--replicas", type=int, default=2)
    ap.add_argument("--secrets", required=True)
    ap.add_argument("--data", required=True)
    ap.add_argument("--ports", required=True, help="free loopback ports, comma-separated, enough for every container port")
    ap.add_argument("--probes", required=True)
    a = ap.parse_args()
    ports = [int(p) for p in a.ports.split(",")]
    objects = [o for o in yaml.safe_load_all(open(a.rendered)) if o]
    out, probes, left_out = [], [], []
    for o in objects:
        kind, name = o["kind"], o["metadata"]["name"]
        if kind not in RUNS:
            left_out.append(f"{kind}/{name}")
            continue
        if kind == "ConfigMap":
            o = copy.deepcopy(o)
            for key, text in o.get("data", {}).items():
                o["data"][key] = text.replace('backend = "cuda"', 'backend = "cpu"')
            out.append(o)
        elif kind == "StatefulSet":
            replicas = min(a.replicas, o["spec"].get("replicas", 1))
            for n in range(replicas):
                template = copy.deepcopy(o["spec"]["template"])
                pod_name = f"{name}-{n}"
                labels = {**template["metadata"].get("labels", {}), "statefulset.kubernetes.io/pod-name": pod_name}
                spec = template["spec"]
                spec.pop("topologySpreadConstraints", None)
                spec["hostname"] = pod_name
                # The pod's own name through the headless Service, which the cluster's DNS would answer
                # with the pod's address; its probes ask it (the name its certificate carries).
                namespace = o["metadata"].get("namespace", "default")
                spec["hostAliases"] = [{"ip": "127.0.0.1",
                                        "hostnames": [f"{pod_name}.{o['spec']['serviceName']}.{namespace}.svc"]}]
                spec["volumes"] = host_paths(spec.get("volumes", []), a.secrets, a.data)
                for c in spec["containers"]:
                    c["image"] = a.server_image
                    for section in ("requests", "limits"):
                        c.get("resources", {}).get(section, {}).pop("nvidia.com/gpu", None)
                    downward_values(c, pod_name, o["metadata"].get("namespace", "default"))
                    expand_args(c)
                    publish(c, ports, probes, pod_name)
                out.append({"apiVersion": "v1", "kind": "Pod",
                            "metadata": {"name": pod_name, "namespace": o["metadata"].get("namespace"), "labels": labels,
                                         "annotations": template["metadata"].get("annotations", {})},
                            "spec": spec})
        elif kind == "Deployment":
            o = copy.deepcopy(o)
            o["spec"]["replicas"] = 1  # podman plays one pod of a Deployment
            spec = o["spec"]["template"]["spec"]
            spec["volumes"] = host_paths(spec.get("volumes", []), a.secrets, a.data)
            for c in spec["containers"]:
                c["image"] = a.web_image
                downward_values(c, f"{name}-pod-0", o["metadata"].get("namespace", "default"))
                expand_args(c)
                publish(c, ports, probes, f"{name}-pod-0")
            out.append(o)
    yaml.safe_dump_all(out, sys.stdout, sort_keys=False)
    with open(a.probes, "w") as f:
        for p in probes:
            f.write(json.dumps(p) + "\n")
    print("not played (podman kube play runs none of these): " + ", ".join(left_out), file=sys.stderr)


if __name__ == "__main__":
    main()
