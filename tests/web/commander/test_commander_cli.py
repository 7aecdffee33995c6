"""``wsg commander`` as a user starts it: serves the page, connects with --url, and Ctrl-C disconnects
with 07h (000 §3.1.2), so the gripper is not left in FAST STOP (000 §1.4.2)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import httpx
import pytest

from pywsg.testing.host import SimThread

from ..conftest import wait_for
from .harness import WireTap

WSG = Path(sys.executable).with_name("wsg")


@pytest.fixture(scope="module")
def sim() -> Iterator[SimThread]:
    with SimThread(model="wsg50", tcp_port=0, udp_port=None) as s:
        yield s


def test_commander_serves_connects_and_ctrl_c_announces_the_disconnect(sim: SimThread) -> None:
    tap = WireTap(sim)
    proc = subprocess.Popen([str(WSG), "commander", "--port", "0", "--url", sim.url], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env={**os.environ, "WSG_NO_ENV": "1"})
    try:
        assert proc.stdout is not None
        line = proc.stdout.readline()
        assert line.startswith("WSG Commander on http://127.0.0.1:"), line
        url = line.split(" on ", 1)[1].split()[0]
        page = httpx.get(url, timeout=30)
        assert page.status_code == 200 and "Custom Command Editor" in page.text
        wait_for(lambda: httpx.get(url + "api/state", timeout=30).json()["connection"]["status"] == "connected")
        tap.clear()
        proc.send_signal(signal.SIGINT)
        assert proc.wait(30) == 130, proc.stderr.read() if proc.stderr else ""
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert bytes.fromhex("AA AA AA 07 00 00") in tap.data
    assert not sim.call(lambda: sim.gripper.snapshot().fast_stop)


def test_commander_is_listed_with_the_tools() -> None:
    r = subprocess.run([str(WSG), "--help"], capture_output=True, text=True, timeout=60,
                       env={**os.environ, "COLUMNS": "120"})
    tools = r.stdout[r.stdout.index("Tools:"):]
    assert "commander" in tools and "WSG Commander" in tools, r.stdout
