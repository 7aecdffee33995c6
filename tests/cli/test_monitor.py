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
from collections.abc import Callable

import pytest

from .conftest import WSG, Sim, run_wsg

ANSI = re.compile(rb"\x1b\[[0-9;?]*[A-Za-z]|\x1b[()][AB0]")


def _frames(text: str) -> list[str]:
    """The monitor's panels, one string each, in order."""
    return [p for p in re.split(r"(?=╭)", text) if "Width" in p]


@pytest.mark.realtime
def test_monitor_in_a_pty(sim: Sim, spawn: Callable[..., subprocess.Popen[bytes]]) -> None:
    """Each step waits for what the screen shows, not for a time: a loaded machine only makes it slower."""
    assert run_wsg("home", url=sim.udp_url).code == 0
    master, slave = pty.openpty()
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 30, 100, 0, 0))
    env = {**os.environ, "TERM": "xterm-256color", "COLUMNS": "100", "LINES": "30"}
    env.pop("NO_COLOR", None)
    # --duration far beyond the test's own patience: the monitor can only end in time by obeying q
    proc = spawn([str(WSG), "--url", sim.url, "monitor", "--duration", "600", "--period", "20"],
                 stdin=slave, stdout=slave, stderr=slave, close_fds=True, env=env)
    os.close(slave)
    out = b""

    def last_panel() -> str:
        panels = _frames(ANSI.sub(b"", out[-20000:]).decode("utf-8", "replace"))
        return panels[-2] if len(panels) > 1 else ""  # the last one may still be arriving

    def moved(panel: str) -> bool:
        m = re.search(r"Width\s+([\d.]+) mm", panel)
        return m is not None and float(m.group(1)) < 100

    # (what the screen must show first, what to do then, what that step waits for)
    steps: list[tuple[Callable[[str], bool], str | bytes, str]] = [
        (lambda p: "Width" in p, "move", "the first panel"),
        (moved, b"f", "a width below 100 mm after `wsg move 20`"),
        (lambda p: "SF_FAST_STOP" in p and "fast-stop: E_SUCCESS" in ANSI.sub(b"", out).decode("utf-8", "replace"),
         b"a", "SF_FAST_STOP and the fast-stop reply after the f key"),
        (lambda p: "SF_FAST_STOP" not in p and "ack: E_SUCCESS" in ANSI.sub(b"", out).decode("utf-8", "replace"),
         b"q", "the acknowledged FAST STOP after the a key"),
    ]
    deadline = time.monotonic() + 120
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
            if steps and steps[0][0](last_panel()):
                _, action, _ = steps.pop(0)
                deadline = time.monotonic() + 120
                if action == "move":  # a second client (UDP) moves the fingers while the monitor watches
                    r = run_wsg("move", "20", "--speed", "100", "--no-wait", url=sim.udp_url)
                    assert r.code == 0, r
                else:
                    assert isinstance(action, bytes)
                    os.write(master, action)
            if time.monotonic() > deadline:
                waited = steps[0][2] if steps else "the monitor to quit on q"
                screen = ANSI.sub(b"", out[-3000:]).decode("utf-8", "replace")
                pytest.fail(f"waited 120 s for {waited}; screen:\n{screen}")
    finally:
        os.close(master)
    assert not steps, f"the monitor ended before {steps[0][2]}"
    assert proc.wait(30) == 0  # q quit it, long before --duration
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
    # ~15 rows in 1.5 s; 4 leave room for a busy machine
    r = sim.wsg("monitor", "--json", "--duration", "1.5", "--refresh", "0.1", "--period", "20")
    assert r.code == 0, r
    import json

    rows = [json.loads(x) for x in r.out.splitlines()]
    assert len(rows) >= 4
    last = rows[-1]
    assert isinstance(last["width"], float) and isinstance(last["flags"], list)
    assert last["gripper_state"] in {"IDLE", "POSITIONING", "HOLDING", "NO_PART", "ERROR", "RELEASING"}
    assert last["temperature"] is not None
