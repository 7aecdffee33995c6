"""The virtual gripper's image, run with podman: configuration, password rule, health check, the driver
and a raw client over TCP and UDP, the world API, SIGTERM (docs/container.md)."""

from __future__ import annotations

import json
import socket
import struct
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from pywsg import Gripper
from pywsg.protocol import GripperState
from pywsg.testing.remote import RemoteWorld

from ..ports import free_base
from .conftest import ROOT, inspect, podman, pytestmark, unique, wait_healthy

__all__ = ["pytestmark"]

PASSWORD = "container-test-password"


class Running:
    """A container of the image with its published ports (TCP, UDP, web) and settings volume."""

    def __init__(self, image: str) -> None:
        self.name = unique("sim")
        self.volume = f"{self.name}-settings"
        self.base = free_base(2)   # TCP and UDP on base, web on base + 1
        podman("volume", "create", self.volume)
        self.started = time.monotonic()
        podman("run", "-d", "--name", self.name, "-e", f"WSG_WEB_PASSWORD={PASSWORD}",
               "-e", "WSG_SIM_MODEL=wsg50", "-v", f"{self.volume}:/var/lib/wsg",
               "-p", f"127.0.0.1:{self.base}:1000/tcp", "-p", f"127.0.0.1:{self.base}:1500/udp",
               "-p", f"127.0.0.1:{self.base + 1}:8080/tcp", image)
        self.web = f"http://127.0.0.1:{self.base + 1}"
        wait_healthy(self.web)
        self.ready_s = time.monotonic() - self.started
        self.world = RemoteWorld(self.web, PASSWORD)

    def remove(self) -> None:
        podman("rm", "-f", "-v", self.name, check=False)
        podman("volume", "rm", "-f", self.volume, check=False)


@pytest.fixture(scope="module")
def sim(image: str) -> Iterator[Running]:
    running = Running(image)
    try:
        yield running
    finally:
        running.remove()


# -- a public-style raw client: frames and the CRC written out as a driver from the manual would ----------

def _crc_table() -> list[int]:
    table = []
    for i in range(256):
        crc = i << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x1021) if crc & 0x8000 else crc << 1
        table.append(crc & 0xFFFF)
    return table


_TABLE = _crc_table()


def crc16(data: bytes) -> int:
    """000 Appendix D: the CCITT table (1021h), start FFFFh, the manual's update rule."""
    crc = 0xFFFF
    for b in data:
        crc = _TABLE[(crc ^ b) & 0xFF] ^ (crc >> 8)
    return crc


def frame(command: int, payload: bytes = b"") -> bytes:
    head = b"\xaa\xaa\xaa" + bytes([command]) + struct.pack("<H", len(payload)) + payload
    return head + struct.pack("<H", crc16(head))


def split(data: bytes) -> tuple[int, int, bytes]:
    """(command ID, status code, rest of the payload) of one reply frame, its CRC checked."""
    assert data[:3] == b"\xaa\xaa\xaa", data.hex()
    size = struct.unpack_from("<H", data, 4)[0]
    assert crc16(data[: 6 + size + 2]) == 0, "the CRC over a whole frame, checksum included, is 0 (000 App. D)"
    return data[3], struct.unpack_from("<H", data, 6)[0], data[8 : 6 + size]


def test_crc_matches_the_manuals_golden_vector() -> None:
    assert frame(0x01) == bytes.fromhex("AAAAAA010000E810")
    assert frame(0x01, b"\x12\x34") == bytes.fromhex("AAAAAA01020012346D66")


# -- the tests ---------------------------------------------------------------------------------------

def test_refuses_to_start_off_loopback_without_a_password(image: str) -> None:
    r = podman("run", "--rm", image, check=False, timeout=120)
    lines = [ln for ln in (r.stdout + r.stderr).splitlines() if ln.strip() and "level=" not in ln]
    assert r.returncode != 0
    assert len(lines) == 1, lines   # one line that says how
    assert "WSG_WEB_PASSWORD" in lines[0] and "WSG_WEB_PASSWORD_FILE" in lines[0]


def test_password_from_a_mounted_secret_file(image: str, tmp_path: Path, cleanup: list[tuple[str, ...]]) -> None:
    secret = tmp_path / "password"
    secret.write_text("from-a-file\n")
    secret.chmod(0o644)
    name = unique("secretfile")
    base = free_base(1)
    cleanup.append(("rm", "-f", "-v", name))
    podman("run", "-d", "--name", name, "-v", f"{secret}:/run/secrets/wsg-web:ro",
           "-e", "WSG_WEB_PASSWORD_FILE=/run/secrets/wsg-web", "-e", "WSG_SIM_TCP_PORT=off",
           "-e", "WSG_SIM_UDP_PORT=off", "-p", f"127.0.0.1:{base}:8080/tcp", image)
    web = f"http://127.0.0.1:{base}"
    wait_healthy(web)
    assert RemoteWorld(web, "from-a-file").state()["gripper_state"] == "IDLE"
    with pytest.raises(Exception, match="401"):
        RemoteWorld(web, "wrong").state()


def test_image_is_labelled_runs_as_non_root_and_has_a_health_check(image: str) -> None:
    info = inspect(image, "image")
    config = info["Config"]
    assert isinstance(config, dict)
    labels = config["Labels"]
    version = next(line.split('"')[1] for line in (ROOT / "pyproject.toml").read_text().splitlines()
                   if line.startswith("version = "))
    assert labels["org.opencontainers.image.version"] == version
    assert labels["org.opencontainers.image.licenses"] == "MIT"
    assert "org.opencontainers.image.source" in labels
    assert config["User"] == "wsg"
    assert "wsg-healthcheck" in info["Healthcheck"]["Test"]  # type: ignore[index]
    assert config["Entrypoint"] == ["wsg", "sim"]


def test_driver_grips_a_part_placed_through_the_world_api(sim: Running) -> None:
    """The in-process fixture's World methods, over HTTP, against the image; the driver over TCP."""
    assert "22 mm" in sim.world.place_part(22.0)
    with Gripper(f"tcp://127.0.0.1:{sim.base}", timeout=10) as g:
        g.home()
        g.grip(22.0, speed=200)
        assert g.gripper_state() == GripperState.HOLDING
    state = sim.world.state()
    assert state["gripper_state"] == "HOLDING" and state["part"] == 22.0
    assert state["fast_stop"] is False   # the driver said goodbye (07h)
    sim.world.remove_part()
    with Gripper(f"tcp://127.0.0.1:{sim.base}", timeout=10) as g:
        g.release(10, speed=200)


def test_driver_over_udp(sim: Running) -> None:
    with Gripper(f"udp://127.0.0.1:{sim.base}?reply_port=0", timeout=10) as g:
        g.home()
        g.move(40.0, speed=200)
        assert g.width() == pytest.approx(40.0, abs=0.1)


def test_raw_client_over_tcp_and_udp(sim: Running) -> None:
    """A client that knows only the manual: Loop (06h) and Get Acceleration (31h) over TCP and UDP."""
    with socket.create_connection(("127.0.0.1", sim.base), timeout=10) as s:
        s.sendall(frame(0x06, b"container"))
        cmd, status, rest = split(s.recv(4096))
        assert (cmd, status, rest) == (0x06, 0, b"container")
        s.sendall(frame(0x31))
        cmd, status, rest = split(s.recv(4096))
        assert (cmd, status, len(rest)) == (0x31, 0, 4)
        s.sendall(frame(0x07))   # announce the disconnect: no FAST STOP
        assert split(s.recv(4096))[:2] == (0x07, 0)
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as u:
        u.settimeout(10)
        u.sendto(frame(0x06, b"udp"), ("127.0.0.1", sim.base))
        data, _ = u.recvfrom(4096)   # the image answers the sender's port
        assert split(data) == (0x06, 0, b"udp")
    assert sim.world.state()["fast_stop"] is False


def test_health_check_never_fast_stops_and_never_takes_the_command_interface(sim: Running) -> None:
    with socket.create_connection(("127.0.0.1", sim.base), timeout=10) as s:
        for _ in range(3):
            r = podman("healthcheck", "run", sim.name, check=False)
            assert r.returncode == 0, r.stdout + r.stderr
        s.sendall(frame(0x06, b"still mine"))   # this client still holds the interface
        assert split(s.recv(4096)) == (0x06, 0, b"still mine")
        s.sendall(frame(0x07))
        split(s.recv(4096))
    assert sim.world.state()["fast_stop"] is False


def test_sigterm_stops_cleanly_and_saves_the_settings(sim: Running) -> None:
    """Last in this module: it stops the container. The tag (000 §3.5.2) lives in the settings file."""
    with Gripper(f"tcp://127.0.0.1:{sim.base}", timeout=10) as g:
        g.set_tag("cell-4 gripper")
    mount = inspect(sim.volume, "volume")["Mountpoint"]
    settings = Path(str(mount)) / "settings.json"
    before = settings.read_text() if settings.exists() else ""
    podman("stop", "--time", "20", sim.name)   # SIGTERM (the image's STOPSIGNAL), SIGKILL after 20 s
    state = inspect(sim.name)["State"]
    assert isinstance(state, dict)
    assert state["ExitCode"] == 0
    logs = podman("logs", sim.name).stdout
    assert logs.strip().endswith("stopping")
    saved = json.loads(settings.read_text())
    assert saved["tag"] == "cell-4 gripper" and "cell-4" not in before
