"""deploy/kubernetes/wsg-cell.yaml played by ``podman kube play`` on this machine: three grippers, each
with its stable name, its own settings volume and ports, the world API behind the Secret (docs/container.md,
"A cell past one host"). Podman 4.3 knows no StatefulSet: deploy/kubernetes/podman_play.py turns the
manifest into the Pods and volume claims it does know (the same pod template)."""

from __future__ import annotations

import base64
import json
import subprocess
import sys
import urllib.error
import urllib.request
from collections.abc import Iterator
from pathlib import Path

import pytest

from pywsg import Gripper
from pywsg.testing.remote import RemoteWorld

from ..ports import free_base
from .conftest import ROOT, podman, pytestmark, unique, wait_healthy

__all__ = ["pytestmark"]

MANIFEST = ROOT / "deploy" / "kubernetes" / "wsg-cell.yaml"
GRIPPERS = 3
PASSWORD = "kube-test-password"


class Cell:
    def __init__(self, image: str, tmp: Path) -> None:
        self.prefix = unique("cell") + "-"
        self.base = free_base(10 * GRIPPERS)
        self.file = tmp / "cell-podman.yaml"
        out = subprocess.run(
            [sys.executable, str(ROOT / "deploy" / "kubernetes" / "podman_play.py"), str(MANIFEST),
             "--replicas", str(GRIPPERS), "--publish", str(self.base), "--prefix", self.prefix, "--image", image],
            capture_output=True, text=True, check=True)
        self.file.write_text(out.stdout)
        secret = tmp / "secret.json"
        secret.write_text(json.dumps({"password": base64.b64encode(PASSWORD.encode()).decode()}))
        self.secret = self.prefix + "wsg-web"
        podman("secret", "create", self.secret, str(secret))
        podman("kube", "play", str(self.file), timeout=300)

    def tcp(self, i: int) -> str:
        return f"tcp://127.0.0.1:{self.base + 10 * i}"

    def udp(self, i: int) -> str:
        return f"udp://127.0.0.1:{self.base + 10 * i + 1}?reply_port=0"

    def web(self, i: int) -> str:
        return f"http://127.0.0.1:{self.base + 10 * i + 2}"

    def remove(self) -> None:
        podman("kube", "down", str(self.file), check=False, timeout=120)
        for i in range(GRIPPERS):
            podman("volume", "rm", "-f", f"{self.prefix}settings-wsg-{i}", check=False)
        podman("secret", "rm", self.secret, check=False)


@pytest.fixture(scope="module")
def cell(image: str, tmp_path_factory: pytest.TempPathFactory) -> Iterator[Cell]:
    c = Cell(image, tmp_path_factory.mktemp("kube"))
    try:
        for i in range(GRIPPERS):
            wait_healthy(c.web(i), timeout=120)
        yield c
    finally:
        c.remove()


def test_each_gripper_has_its_stable_name(cell: Cell) -> None:
    for i in range(GRIPPERS):
        out = podman("exec", f"{cell.prefix}wsg-{i}-gripper", "python3", "-c",
                     "import socket; print(socket.gethostname())").stdout.strip()
        assert out == f"wsg-{i}"


def test_each_gripper_is_driven_on_its_own(cell: Cell) -> None:
    """Three independent grippers: each moves to its own width over TCP, is read over UDP, and the world
    API (password from the Secret) sees each at its own width."""
    widths = [20.0 + 15 * i for i in range(GRIPPERS)]
    for i, w in enumerate(widths):
        with Gripper(cell.tcp(i), timeout=10) as g:
            g.home()
            g.move(w, speed=200)
    for i, w in enumerate(widths):
        with Gripper(cell.udp(i), timeout=10) as g:
            assert g.width() == pytest.approx(w, abs=0.1)
        state = RemoteWorld(cell.web(i), PASSWORD).state()
        assert state["width"] == pytest.approx(w, abs=0.1) and state["fast_stop"] is False


def test_world_api_needs_the_secret(cell: Cell) -> None:
    with pytest.raises(Exception, match="401"):
        RemoteWorld(cell.web(0)).state()
    assert "part of 30 mm" in RemoteWorld(cell.web(1), PASSWORD).place_part(30.0)
    assert RemoteWorld(cell.web(1), PASSWORD).state()["part"] == 30.0
    assert RemoteWorld(cell.web(2), PASSWORD).state()["part"] is None


def test_probes_are_the_health_route(cell: Cell) -> None:
    """The pod's probes as podman sees them (readiness/liveness -> the container's health check)."""
    info = json.loads(podman("container", "inspect", f"{cell.prefix}wsg-0-gripper").stdout)[0]
    check = info["Config"].get("Healthcheck") or {}
    assert "wsg-healthcheck" in check.get("Test", []), check
    assert podman("healthcheck", "run", f"{cell.prefix}wsg-0-gripper", check=False).returncode == 0


def test_web_interface_answers_to_the_pod_and_service_names(cell: Cell) -> None:
    """WSG_SIM_WEB_ALLOWED_HOSTS = "$(POD_NAME) $(POD_NAME).wsg": a cell test reaches gripper 1 as
    http://wsg-1:8080 or http://wsg-1.wsg:8080; another name is refused (the DNS-rebinding guard)."""
    def status(host: str) -> int:
        req = urllib.request.Request(cell.web(1) + "/api/world", headers={
            "Host": host, "Authorization": f"Bearer {PASSWORD}"})
        try:
            with urllib.request.urlopen(req, timeout=10) as reply:
                return int(reply.status)
        except urllib.error.HTTPError as exc:
            return int(exc.code)

    assert status("wsg-1:8080") == 200
    assert status("wsg-1.wsg:8080") == 200
    assert status("wsg-0:8080") == 400
    assert status("rebind.example:8080") == 400
