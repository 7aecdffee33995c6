"""The CI recipes of docs/container.md, run as written (the image and host ports substituted): the GitHub
Actions and GitLab CI `services:` blocks and the compose file."""

from __future__ import annotations

import os
import re
import shlex
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest
import yaml

from pywsg import Gripper
from pywsg.testing.remote import RemoteWorld

from ..ports import free_base
from .conftest import CONF, ROOT, podman, pytestmark, unique, wait_healthy

__all__ = ["pytestmark"]

DOC = (ROOT / "docs" / "container.md").read_text()


def yaml_block(after_heading: str) -> str:
    """The first ```yaml block under the heading ``after_heading``."""
    start = DOC.index(after_heading)
    m = re.compile(r"```yaml\n(.*?)```", re.S).search(DOC, start)
    assert m is not None, after_heading
    return m.group(1)


def wait_health_status(name: str, timeout: float = 60) -> None:
    """Run the image's health check until it passes, as the CI runner does before the job's steps."""
    deadline = time.monotonic() + timeout
    while podman("healthcheck", "run", name, check=False).returncode != 0:
        assert time.monotonic() < deadline, f"{name} never became healthy"
        time.sleep(0.5)


def test_podman_run_recipe(image: str, cleanup: list[tuple[str, ...]]) -> None:
    """The `podman run` line and the `wsg world` line of "Running it", host ports and name substituted."""
    line = next(ln.strip() for ln in DOC.replace("\\\n", " ").splitlines() if ln.strip().startswith("podman run -d"))
    base = free_base(2)
    name = unique("run")
    line = (line.replace("--name gripper", f"--name {name}").replace("pywsg-sim:0.4.0", image)
            .replace("127.0.0.1:1000:", f"127.0.0.1:{base}:").replace("127.0.0.1:1500:", f"127.0.0.1:{base}:")
            .replace("127.0.0.1:8080:", f"127.0.0.1:{base + 1}:"))
    cleanup.append(("rm", "-f", "-v", name))
    podman(*shlex.split(line)[1:])
    wait_healthy(f"http://127.0.0.1:{base + 1}")
    world = next(ln.strip() for ln in DOC.splitlines() if ln.strip().startswith("wsg world --sim"))
    argv = shlex.split(world.replace("127.0.0.1:8080", f"127.0.0.1:{base + 1}"))
    r = subprocess.run([sys.executable, "-c", "from pywsg.cli.main import main; main()", *argv[1:]],
                       capture_output=True, text=True, timeout=60, env=dict(os.environ, WSG_NO_ENV="1"))
    assert r.returncode == 0 and "part of 22 mm" in r.stdout, r.stdout + r.stderr
    with Gripper(f"tcp://127.0.0.1:{base}", timeout=10) as g:
        g.home()
        g.grip(22.0, speed=200)
    with Gripper(f"udp://127.0.0.1:{base}?reply_port=0", timeout=10) as g:
        assert g.width() == pytest.approx(22.0, abs=0.5)


def test_github_actions_service(image: str, cleanup: list[tuple[str, ...]]) -> None:
    """`services.gripper` as the runner starts it: docker create with env, ports and options."""
    job = yaml.safe_load(yaml_block("### GitHub Actions"))["jobs"]["test"]
    service: dict[str, Any] = job["services"]["gripper"]
    base = free_base(2)
    host_port = {"1000": base, "1500/udp": base, "8080": base + 1}
    name = unique("gha")
    args = ["run", "-d", "--name", name]
    for key, value in service["env"].items():
        args += ["-e", f"{key}={value}"]
    for spec in service["ports"]:
        container = spec.split(":", 1)[1]
        args += ["-p", f"127.0.0.1:{host_port[container]}:{container}"]
    args += shlex.split(service["options"])
    cleanup.append(("rm", "-f", "-v", name))
    podman(*args, image)
    wait_health_status(name)
    with Gripper(f"tcp://127.0.0.1:{base}", timeout=10) as g:
        g.home()
    with Gripper(f"udp://127.0.0.1:{base}?reply_port=0", timeout=10) as g:
        assert g.width() > 0
    assert RemoteWorld(f"http://127.0.0.1:{base + 1}", service["env"]["WSG_WEB_PASSWORD"]).state()["model"] == "wsg50"


def test_gitlab_ci_service(image: str, cleanup: list[tuple[str, ...]]) -> None:
    """The service under its alias on a network of its own, and the job's script in a second container on
    it. The job image (python:3.11 + `pip install pywsg`) is replaced by the test image, which has pywsg."""
    job = yaml.safe_load(yaml_block("### GitLab CI"))["test"]
    service = job["services"][0]
    network = unique("gitlab")
    name = unique("gitlab-svc")
    cleanup.append(("network", "rm", "-f", network))
    cleanup.append(("rm", "-f", "-v", name))
    podman("network", "create", network)
    args = ["run", "-d", "--name", name, "--network", network, "--network-alias", service["alias"]]
    for key, value in service["variables"].items():
        args += ["-e", f"{key}={value}"]
    podman(*args, image)
    wait_health_status(name)
    script = [line for line in job["script"] if not line.startswith("pip install")]
    env: list[str] = []
    for key, value in job["variables"].items():
        env += ["-e", f"{key}={value}"]
    r = podman("run", "--rm", "--network", network, *env, "--entrypoint", "sh", image, "-ec",
               " && ".join(script), check=False, timeout=120)
    assert r.returncode == 0, r.stdout + r.stderr
    logs = podman("exec", name, "wsg", "world", "--password", service["variables"]["WSG_WEB_PASSWORD"],
                  "--sim", "http://127.0.0.1:8080", "state").stdout
    assert "HOLDING" in logs and "22 mm" in logs


def test_compose_file_is_the_documented_one_and_runs(image: str, tmp_path: Path) -> None:
    text = (ROOT / "deploy" / "compose.yaml").read_text()
    assert text == yaml_block("### compose")
    work = tmp_path / "cell"
    work.mkdir()
    (work / "compose.yaml").write_text(text)
    password = "compose-test-password"
    secret = work / "wsg-web-password.txt"
    secret.write_text(password + "\n")
    secret.chmod(0o644)
    base = free_base(6)
    ports = {"LEFT_TCP": base, "LEFT_UDP": base, "LEFT_WEB": base + 1,
             "RIGHT_TCP": base + 2, "RIGHT_UDP": base + 2, "RIGHT_WEB": base + 3}
    env = dict(os.environ, CONTAINERS_CONF=str(CONF), WSG_IMAGE=image, **{k: str(v) for k, v in ports.items()})
    project = unique("compose")
    compose = [str(Path(sys.executable).parent / "podman-compose"), "-p", project, "-f", str(work / "compose.yaml")]
    try:
        r = subprocess.run([*compose, "up", "-d"], cwd=work, env=env, capture_output=True, text=True, timeout=300)
        assert r.returncode == 0, r.stdout + r.stderr
        for side, model in (("LEFT", "wsg50"), ("RIGHT", "wsg32")):
            web = f"http://127.0.0.1:{ports[side + '_WEB']}"
            wait_healthy(web)
            world = RemoteWorld(web, password)
            assert world.state()["model"] == model
            world.place_part(20.0)
            with Gripper(f"tcp://127.0.0.1:{ports[side + '_TCP']}", timeout=10) as g:
                g.home()
                g.grip(20.0, speed=200)
            with Gripper(f"udp://127.0.0.1:{ports[side + '_UDP']}?reply_port=0", timeout=10) as g:
                assert g.width() == pytest.approx(20.0, abs=0.5)
    finally:
        subprocess.run([*compose, "down", "-v"], cwd=work, env=env, capture_output=True, timeout=300)
    left = podman("ps", "-a", "--filter", f"label=io.podman.compose.project={project}", "-q").stdout.strip()
    assert left == ""
