#!/usr/bin/env python3
"""Turn deploy/kubernetes/wsg-cell.yaml into what ``podman kube play`` (Podman 4.3) runs on one machine.

Podman 4.3's ``kube play`` knows Pods, Deployments and PersistentVolumeClaims, not StatefulSets, Services
or Secrets. From the same manifest this writes:

- one Pod per replica, named as the StatefulSet names its pods (``wsg-0``, ``wsg-1``, ...; hostname too),
  with the StatefulSet's pod template unchanged (image, environment, probes, security context);
- one PersistentVolumeClaim per pod for each volumeClaimTemplate (``settings-wsg-0``, ...), mounted as
  the StatefulSet would (Podman makes a named volume of each);
- the Secret's data as the JSON that ``podman secret create NAME -`` takes (``--secret-json FILE``);
  ``secretKeyRef`` then finds it by name;
- ``$(VAR)`` references in environment values expanded, and ``fieldRef: metadata.name`` given the pod's
  name, as Kubernetes does (Podman 4.3 leaves the text as it is);
- httpGet probes of /healthz as the image's ``wsg-healthcheck`` command (Podman makes ``curl`` commands of
  them, and the image has no curl);
- with ``--publish BASE``, each pod's container ports on the host's loopback: gripper i's port
  number k (in the order the manifest lists them) on ``BASE + 10*i + k`` (a Service's role on one machine).

Services are left out: on one machine the pods are reached through the published ports.

    python3 deploy/kubernetes/podman_play.py deploy/kubernetes/wsg-cell.yaml --replicas 3 --publish 20000 \\
        --secret-json secret.json > cell-podman.yaml
    podman secret create wsg-web secret.json
    podman kube play cell-podman.yaml          # ... podman kube down cell-podman.yaml

``--prefix P`` puts P before every pod, volume and secret name (tests run beside each other). Needs PyYAML.
"""

from __future__ import annotations

import argparse
import base64
import copy
import json
import re
import sys
from typing import Any

import yaml


def convert(docs: list[dict[str, Any]], *, replicas: int | None = None, publish: int | None = None,
            prefix: str = "", image: str | None = None) -> tuple[list[dict[str, Any]], dict[str, dict[str, str]]]:
    """(the documents for ``podman kube play``, {secret name: JSON-able data for ``podman secret create``})."""
    out: list[dict[str, Any]] = []
    secrets: dict[str, dict[str, str]] = {}
    for doc in docs:
        kind = doc.get("kind")
        if kind == "Secret":
            data = {k: str(v) for k, v in (doc.get("data") or {}).items()}
            data.update({k: base64.b64encode(str(v).encode()).decode() for k, v in
                         (doc.get("stringData") or {}).items()})
            secrets[prefix + doc["metadata"]["name"]] = data   # Podman 4.3: a flat JSON map, base64 values
        elif kind == "StatefulSet":
            out.extend(_pods(doc, replicas, publish, prefix, image))
        elif kind in ("Pod", "Deployment", "PersistentVolumeClaim", "ConfigMap"):
            out.append(doc)
        # Service: nothing to do on one machine (the pods' ports are published instead)
    return out, secrets


def _pods(sts: dict[str, Any], replicas: int | None, publish: int | None, prefix: str,
          image: str | None) -> list[dict[str, Any]]:
    name = sts["metadata"]["name"]
    spec = sts["spec"]
    n = spec.get("replicas", 1) if replicas is None else replicas
    out: list[dict[str, Any]] = []
    for i in range(n):
        pod_name = f"{prefix}{name}-{i}"
        template = copy.deepcopy(spec["template"])
        pod_spec = template["spec"]
        pod_spec["hostname"] = f"{name}-{i}"
        volumes = pod_spec.setdefault("volumes", [])
        for claim in spec.get("volumeClaimTemplates", []):
            claim_name = f"{prefix}{claim['metadata']['name']}-{name}-{i}"
            out.append({"apiVersion": "v1", "kind": "PersistentVolumeClaim",
                        "metadata": {"name": claim_name}, "spec": claim["spec"]})
            volumes.append({"name": claim["metadata"]["name"], "persistentVolumeClaim": {"claimName": claim_name}})
        for container in pod_spec["containers"]:
            if image:
                container["image"] = image
            for probe in ("readinessProbe", "livenessProbe", "startupProbe"):
                if "httpGet" in container.get(probe, {}):
                    container[probe]["exec"] = {"command": _http_probe(container[probe].pop("httpGet"))}
            for env in container.get("env", []):
                ref = (env.get("valueFrom") or {}).get("secretKeyRef")
                if ref is not None:
                    ref["name"] = prefix + ref["name"]
                field = (env.get("valueFrom") or {}).get("fieldRef", {}).get("fieldPath")
                if field == "metadata.name":   # the name Kubernetes gives the pod, not the prefixed one
                    env.pop("valueFrom")
                    env["value"] = f"{name}-{i}"
            _expand(container.get("env", []))
            if publish is not None:
                for k, port in enumerate(container.get("ports", [])):
                    port["hostPort"] = publish + 10 * i + k
                    port["hostIP"] = "127.0.0.1"
        labels = dict(template.get("metadata", {}).get("labels", {}))
        labels["statefulset.kubernetes.io/pod-name"] = f"{name}-{i}"
        out.append({"apiVersion": "v1", "kind": "Pod",
                    "metadata": {"name": pod_name, "labels": labels}, "spec": pod_spec})
    return out


def _expand(env: list[dict[str, Any]]) -> None:
    """Kubernetes' ``$(VAR)`` references to variables defined earlier in the list (Podman 4.3 keeps them as
    text); ``$$`` is a literal ``$``, an unknown reference stays as it is, as in Kubernetes."""
    known: dict[str, str] = {}
    for item in env:
        if "value" in item:
            item["value"] = re.sub(r"\$\$|\$\(([A-Za-z_][A-Za-z0-9_.-]*)\)",
                                   lambda m: "$" if m.group(0) == "$$" else known.get(m.group(1), m.group(0)),
                                   str(item["value"]))
            known[item["name"]] = item["value"]


def _http_probe(get: dict[str, Any]) -> list[str]:
    """An httpGet probe of /healthz as a command: Podman runs every probe as a command in the container and
    makes ``curl`` of an httpGet probe, which the image does not have; the image's ``wsg-healthcheck`` asks
    the same route. (Podman 4.3 also splits an exec probe's words at spaces: a one-word script survives.)"""
    if get.get("path") != "/healthz":
        raise ValueError(f"httpGet probe of {get.get('path')!r}: only /healthz has a command form (wsg-healthcheck)")
    return ["wsg-healthcheck", str(get["port"])]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("manifest")
    ap.add_argument("--replicas", type=int, default=None, help="pods of the StatefulSet (default: its replicas)")
    ap.add_argument("--publish", type=int, default=None, metavar="BASE",
                    help="publish gripper i's k-th port on 127.0.0.1:BASE+10*i+k")
    ap.add_argument("--prefix", default="", help="before every pod, volume and secret name")
    ap.add_argument("--image", default=None, help="another image than the manifest's")
    ap.add_argument("--secret-json", default=None, metavar="FILE",
                    help="write the Secret's data here (for `podman secret create NAME FILE`)")
    args = ap.parse_args(argv)
    with open(args.manifest, encoding="utf-8") as f:
        docs = [d for d in yaml.safe_load_all(f) if d]
    out, secrets = convert(docs, replicas=args.replicas, publish=args.publish, prefix=args.prefix,
                           image=args.image)
    if args.secret_json:
        if len(secrets) != 1:
            ap.error(f"--secret-json: the manifest has {len(secrets)} Secrets, not one")
        with open(args.secret_json, "w", encoding="utf-8") as f:
            json.dump(next(iter(secrets.values())), f)
    yaml.safe_dump_all(out, sys.stdout, sort_keys=False)
    return 0


if __name__ == "__main__":
    sys.exit(main())
