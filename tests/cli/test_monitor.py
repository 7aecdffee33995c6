"""`wsg monitor` under a real pseudo-terminal: live values, sparkline, keys f (FAST STOP), a (ack), q (quit)."""

from __future__ import annotations

import fcntl
import os
import pty
import re
import select
import struct
import subprocess
import termios
import time

import pytest

from .conftest import WSG, Sim, run_wsg

ANSI = re.compile(rb"\x1b\[[0-9;?]*[A-Za-z]|\x1b[()][AB0]")


def _frames(text: str) -> list[str]:
    """The monitor's panels, one string each, in order."""
    return [p for p in re.split(r"(?=╭)", text) if "Width" in p]


@pytest.mark.realtime
def test_monitor_in_a_pty(sim: Sim) -> None:
    assert run_wsg("home", url=sim.udp_url).code == 0
    master, slave = pty.openpty()
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 30, 100, 0, 0))
    env = {**os.environ, "TERM": "xterm-256color", "COLUMNS": "100", "LINES": "30"}
    env.pop("NO_COLOR", None)
    proc = subprocess.Popen([str(WSG), "--url", sim.url, "monitor", "--duration", "8", "--period", "20"],
                            stdin=slave, stdout=slave, stderr=slave, close_fds=True, env=env)
    os.close(slave)
    out = b""
    t0 = time.monotonic()
    steps = [(1.0, "move"), (2.2, b"f"), (3.0, b"a"), (3.6, b"q")]
    try:
        while proc.poll() is None or select.select([master], [], [], 0)[0]:
            ready, _, _ = select.select([master], [], [], 0.05)
            if ready:
                try:
                    chunk = os.read(master, 65536)
                except OSError:  # EIO: the child closed the terminal
                    break
                if not chunk:
                    break
                out += chunk
            if steps and time.monotonic() - t0 >= steps[0][0]:
                _, action = steps.pop(0)
                if action == "move":  # a second client (UDP) moves the fingers while the monitor watches
                    r = run_wsg("move", "20", "--speed", "100", "--no-wait", url=sim.udp_url)
                    assert r.code == 0, r
                else:
                    assert isinstance(action, bytes)
                    os.write(master, action)
            if time.monotonic() - t0 > 15:
                proc.kill()
                pytest.fail("monitor did not quit on q")
    finally:
        os.close(master)
    elapsed = time.monotonic() - t0
    assert proc.wait(5) == 0
    assert elapsed < 7, "q must quit before --duration"
    text = ANSI.sub(b"", out).decode("utf-8", "replace")
    panels = _frames(text)
    assert len(panels) > 10, text[-2000:]  # refreshed in place many times
    widths = [float(m) for m in re.findall(r"Width\s+([\d.]+) mm", text)]
    assert widths[0] == pytest.approx(110.0, abs=0.5) and min(widths) < 100, widths  # saw the move
    sparks = re.findall(r"Width\s+[\d.]+ mm\s+([▁▂▃▄▅▆▇█]+)", text)
    assert any(len(set(s)) > 1 for s in sparks), "the width sparkline shows the motion"
    assert any("SF_FAST_STOP" in p for p in panels) and "fast-stop: E_SUCCESS" in text
    assert "ack: E_SUCCESS" in text
    assert "SF_FAST_STOP" not in panels[-1]
    for label in ("Speed", "Force", "State", "Flags", "Temp", "mm/s", "°C"):
        assert label in panels[-1]


def test_monitor_json_lines(sim: Sim) -> None:
    r = sim.wsg("monitor", "--json", "--duration", "0.5", "--refresh", "0.1", "--period", "20")
    assert r.code == 0, r
    import json

    rows = [json.loads(x) for x in r.out.splitlines()]
    assert len(rows) >= 4
    last = rows[-1]
    assert isinstance(last["width"], float) and isinstance(last["flags"], list)
    assert last["gripper_state"] in {"IDLE", "POSITIONING", "HOLDING", "NO_PART", "ERROR", "RELEASING"}
    assert last["temperature"] is not None
