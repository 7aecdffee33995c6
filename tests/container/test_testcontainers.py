"""pywsg.testing.containers.WsgSimContainer (testcontainers) against Podman's Docker API socket: it waits
until the gripper serves without a FAST STOP, and exposes .url, .udp_url, .web_url and .world."""

from __future__ import annotations

import os
import subprocess
import time
import urllib.request
from collections.abc import Iterator
from pathlib import Path

import pytest

from pywsg import Gripper
from pywsg.protocol import GripperState

from .conftest import CONF, ROOT, podman, pytestmark

__all__ = ["pytestmark"]


@pytest.fixture(scope="module")
def docker_host(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    """``podman system service`` on a socket of this test's own (what a Podman user points DOCKER_HOST at)."""
    sock = Path(tmp_path_factory.mktemp("podman")) / "podman.sock"
    env = dict(os.environ, CONTAINERS_CONF=str(CONF))
    proc = subprocess.Popen(["podman", "system", "service", "--time=0", f"unix://{sock}"], env=env,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 60
        while not sock.exists():
            assert proc.poll() is None, "podman system service ended"
            assert time.monotonic() < deadline, "podman system service made no socket"
            time.sleep(0.05)
        yield f"unix://{sock}"
    finally:
        proc.terminate()
        proc.wait(timeout=30)


@pytest.fixture
def tc_settings(docker_host: str, monkeypatch: pytest.MonkeyPatch) -> None:
    """What docs/container.md tells a Podman user to export, set for this test only."""
    from testcontainers.core.config import ConnectionMode, testcontainers_config

    monkeypatch.setenv("DOCKER_HOST", docker_host)
    monkeypatch.setattr(testcontainers_config, "ryuk_disabled", True)   # TESTCONTAINERS_RYUK_DISABLED=true
    # TESTCONTAINERS_CONNECTION_MODE=docker_host (read when testcontainers is imported)
    monkeypatch.setattr(testcontainers_config, "connection_mode_override", ConnectionMode.docker_host)


def test_container_fixture_serves_a_gripper_with_its_world(image: str, tc_settings: None) -> None:
    from pywsg.testing.containers import WsgSimContainer

    with WsgSimContainer(image, ulimits={"nofile": 4096, "nproc": 4096}) as sim:
        name = sim.get_wrapped_container().name
        assert sim.start_seconds is not None
        # waiting for it opened no session: no FAST STOP, nobody holds the command interface
        assert sim.world.state()["fast_stop"] is False
        with urllib.request.urlopen(sim.web_url + "/healthz", timeout=5) as reply:
            assert reply.status == 200
        assert "22 mm" in sim.world.place_part(22.0)
        with Gripper(sim.url, timeout=10) as g:
            g.home()
            g.grip(22.0, speed=200)
            assert g.gripper_state() == GripperState.HOLDING
        with Gripper(sim.udp_url, timeout=10) as g:
            assert g.width() == pytest.approx(22.0, abs=0.5)
        assert sim.world.state()["gripper_state"] == "HOLDING"
        assert sim.url.startswith("tcp://127.0.0.1:")   # published on loopback only
    assert podman("container", "exists", name, check=False).returncode != 0   # removed


def test_the_documented_example_runs(image: str, tc_settings: None) -> None:
    """docs/container.md's testcontainers example, as written but for the image's name."""
    doc = (ROOT / "docs" / "container.md").read_text()
    start = doc.index("### testcontainers (Python)")
    block = doc[doc.index("```python\n", start) + 10 : doc.index("```\n", doc.index("```python\n", start) + 10)]
    assert '"pywsg-sim:0.4.0"' in block
    namespace: dict[str, object] = {}
    exec(compile(block.replace('"pywsg-sim:0.4.0"', repr(image)), "docs/container.md", "exec"), namespace)
    namespace["test_pick"]()  # type: ignore[operator]
