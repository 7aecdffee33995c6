"""``wsg sim`` as a user runs it: a real process, real ports, SIGTERM."""

from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

import pytest

from pywsg.protocol import Status

from ..ports import free_base
from .conftest import TcpClient, UdpClient


def start_sim(*args: str, lines: int) -> tuple[subprocess.Popen[str], list[str]]:
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    proc = subprocess.Popen(
        [sys.executable, "-c", "from pywsg.cli.main import main; main()", "sim", *args],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
    )
    out: list[str] = []
    assert proc.stdout is not None
    deadline = time.monotonic() + 20
    while len(out) < lines:
        line = proc.stdout.readline()
        if not line:
            err = proc.stderr.read() if proc.stderr else ""
            raise AssertionError(f"wsg sim exited early: {out} {err}")
        out.append(line.rstrip("\n"))
        assert time.monotonic() < deadline
    return proc, out


def stop(proc: subprocess.Popen[str]) -> tuple[int, str]:
    proc.send_signal(signal.SIGTERM)
    try:
        rc = proc.wait(10)
    except subprocess.TimeoutExpired:
        proc.kill()
        raise
    rest = proc.stdout.read() if proc.stdout else ""
    return rc, rest


def test_wsg_sim_two_grippers_tcp_udp_pty_then_sigterm(tmp_path: Path) -> None:
    base = free_base(2)
    settings = tmp_path / "wsg.json"
    proc, lines = start_sim(
        "--tcp-port", str(base), "--udp-port", str(base + 100), "--udp-reply-port", "0",
        "--serial", "pty", "--web-port", "off", "--settings", str(settings), "--count", "2", "--no-uvloop",
        lines=6,
    )
    try:
        assert lines[0] == f"gripper 0: TCP      tcp://127.0.0.1:{base}"
        assert lines[3] == f"gripper 1: TCP      tcp://127.0.0.1:{base + 1}"
        assert lines[1].startswith(f"gripper 0: UDP      udp://127.0.0.1:{base + 100}")
        assert lines[2].startswith("gripper 0: serial   serial:///dev/")
        for i in range(2):
            c = TcpClient(base + i)
            assert c.request(0x06, b"fleet").params == b"fleet"
            assert c.request(0x07).status == Status.E_SUCCESS
            c.close()
            u = UdpClient(base + 100 + i)
            assert u.request(0x06, b"udp").params == b"udp"
            u.close()
    finally:
        rc, rest = stop(proc)
    assert rc == 0
    assert "stopping" in rest
    assert settings.exists() and json.loads(settings.read_text())  # settings saved on SIGTERM
    with pytest.raises(OSError):  # sockets closed
        socket.create_connection(("127.0.0.1", base), timeout=1)


def test_wsg_sim_modbus_and_web_interfaces() -> None:
    pytest.importorskip("pymodbus")
    pytest.importorskip("uvicorn")
    base = free_base(3)
    proc, lines = start_sim(
        "--tcp-port", str(base), "--udp-port", "off", "--serial", "off", "--modbus-port", str(base + 1),
        "--web-port", str(base + 2), lines=3,
    )
    try:
        assert lines[1] == f"gripper 0: Modbus   modbus-tcp://127.0.0.1:{base + 1}"
        assert lines[2] == f"gripper 0: web      http://127.0.0.1:{base + 2}/"
        c = TcpClient(base)  # default loop: uvloop when installed
        assert c.request(0x06, b"uv").params == b"uv"
        c.request(0x07)
        c.close()
        from pymodbus.client import ModbusTcpClient

        mb = ModbusTcpClient("127.0.0.1", port=base + 1)
        assert mb.connect()
        rr = mb.read_input_registers(0, count=6, device_id=1)
        assert not rr.isError() and len(rr.registers) == 6
        mb.close()
        with urllib.request.urlopen(f"http://127.0.0.1:{base + 2}/", timeout=5) as resp:
            assert resp.status == 200
    finally:
        rc, _ = stop(proc)
    assert rc == 0


def test_wsg_sim_web_allowed_host_admits_that_name_only() -> None:
    """--web-allowed-host NAME: the web interface answers Host: NAME; other names stay refused (400)."""
    import http.client

    proc, lines = start_sim(
        "--tcp-port", "off", "--udp-port", "off", "--serial", "off", "--web-port", "0",
        "--web-allowed-host", "gripper.lab", "--web-allowed-host", "cell7.example", lines=1,
    )
    try:
        port = int(lines[0].rsplit(":", 1)[1].rstrip("/"))

        def status(host: str) -> int:
            conn = http.client.HTTPConnection("127.0.0.1", port, timeout=5)
            conn.request("GET", "/api/state", headers={"Host": f"{host}:{port}"})
            code = conn.getresponse().status
            conn.close()
            return code

        assert status("gripper.lab") != 400
        assert status("cell7.example") != 400
        assert status("127.0.0.1") != 400
        assert status("rebind.example") == 400
    finally:
        rc, _ = stop(proc)
    assert rc == 0


def test_wsg_sim_web_request_rate_options() -> None:
    """--web-request-rate/--web-request-burst set the per-client limit; rate 0 turns it off."""
    import http.client

    def statuses(*args: str) -> list[int]:
        proc, lines = start_sim("--tcp-port", "off", "--udp-port", "off", "--serial", "off", "--web-port", "0",
                                *args, lines=1)
        try:
            port = int(lines[0].rsplit(":", 1)[1].rstrip("/"))
            got = []
            for _ in range(4):
                conn = http.client.HTTPConnection("127.0.0.1", port, timeout=5)
                conn.request("GET", "/api/state")
                got.append(conn.getresponse().status)
                conn.close()
            return got
        finally:
            rc, _ = stop(proc)
            assert rc == 0

    assert statuses("--web-request-rate", "0.01", "--web-request-burst", "2") == [200, 200, 429, 429]
    assert statuses("--web-request-rate", "0", "--web-request-burst", "2") == [200] * 4


def test_wsg_sim_port_in_use_is_a_clear_error() -> None:
    blocker = socket.socket()
    blocker.bind(("127.0.0.1", 0))
    blocker.listen()
    port = blocker.getsockname()[1]
    try:
        r = subprocess.run(
            [sys.executable, "-c", "from pywsg.cli.main import main; main()", "sim", "--tcp-port", str(port),
             "--udp-port", "off", "--serial", "off", "--web-port", "off"],
            capture_output=True, text=True, timeout=20,
        )
    finally:
        blocker.close()
    assert r.returncode != 0
    assert "cannot listen" in r.stderr and "Traceback" not in r.stderr
