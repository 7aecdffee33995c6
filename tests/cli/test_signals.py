"""A `wsg` command stopped by a signal announces its disconnect, so the gripper stays out of FAST STOP.

Command manual 000 §3.1.2: closing the TCP connection without 07h raises FAST STOP. `timeout 0.8 wsg move 0`
sends SIGTERM, a closed terminal sends SIGHUP, Ctrl-C SIGINT; each must unwind, send 07h, and exit 128 + N.
Real processes, real signals, a real `wsg sim` - one per test: a `wsg` that hangs holds the TCP session of its
own sim only, never one a later test needs. Every `wsg` started here is killed at teardown (``spawn``).
"""

from __future__ import annotations

import signal
import subprocess
import time
from collections.abc import Callable, Iterator
from typing import Any

import pytest

from .conftest import WSG, Sim, run_wsg

Spawn = Callable[..., "subprocess.Popen[Any]"]


def _flags(sim: Sim) -> list[str]:
    r = run_wsg("--json", "flags", url=sim.udp_url)  # UDP: readable while another client holds TCP
    assert r.code == 0, r
    flags: list[str] = r.json()["flags"]
    return flags


def _wait_moving(sim: Sim, proc: subprocess.Popen[str]) -> None:
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:
        assert proc.poll() is None, proc.communicate()
        if "SF_MOVING" in _flags(sim):
            return
        time.sleep(0.1)
    raise AssertionError("the fingers did not start moving within 60 s of `wsg move 0`")


def _start_slow_move(sim: Sim, spawn: Spawn) -> subprocess.Popen[str]:
    assert run_wsg("move", "100", "--speed", "400", url=sim.url).code == 0
    return spawn([str(WSG), "--url", sim.url, "move", "0", "--speed", "5"],
                 stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def _exit(proc: subprocess.Popen[str], what: str) -> tuple[str, str]:
    """(stdout, stderr) once ``proc`` has exited; it gets 60 s (a loaded machine), then the test fails."""
    try:
        return proc.communicate(timeout=60)
    except subprocess.TimeoutExpired:
        pytest.fail(f"`wsg` did not exit within 60 s of {what}")


@pytest.fixture
def homed() -> Iterator[Sim]:
    s = Sim()
    try:
        assert run_wsg("home", url=s.url).code == 0
        yield s
    finally:
        s.stop()


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGHUP, signal.SIGINT], ids=lambda s: s.name)
def test_signal_during_a_motion_announces_the_disconnect(homed: Sim, sig: signal.Signals, spawn: Spawn) -> None:
    proc = _start_slow_move(homed, spawn)
    _wait_moving(homed, proc)
    proc.send_signal(sig)
    out, err = _exit(proc, sig.name)
    assert proc.returncode == 128 + sig, (out, err)  # 143 SIGTERM, 129 SIGHUP, 130 Ctrl-C
    assert "Traceback" not in err
    assert f"stopped by {sig.name}" in err
    assert "SF_FAST_STOP" not in _flags(homed)


def test_without_the_handling_an_unannounced_close_does_raise_fast_stop(homed: Sim, spawn: Spawn) -> None:
    """The control experiment: SIGKILL cannot be handled, and the gripper does what the manual says."""
    proc = _start_slow_move(homed, spawn)
    _wait_moving(homed, proc)
    proc.kill()
    _exit(proc, "SIGKILL")
    deadline = time.monotonic() + 30
    while "SF_FAST_STOP" not in _flags(homed):
        assert time.monotonic() < deadline, "no FAST STOP within 30 s of an unannounced close"
        time.sleep(0.1)
    r = run_wsg("ack", url=homed.url)
    assert r.code == 0, r
    assert "SF_FAST_STOP" not in _flags(homed)


def test_terminal_closed_on_wsg_monitor_leaves_no_fast_stop(homed: Sim, spawn: Spawn) -> None:
    proc = spawn([str(WSG), "--url", homed.url, "monitor", "--json", "--refresh", "0.1"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    assert proc.stdout is not None
    assert proc.stdout.readline().startswith("{")  # it is connected and streaming
    proc.send_signal(signal.SIGHUP)
    _out, err = _exit(proc, "SIGHUP")
    assert proc.returncode == 129, err
    assert "Traceback" not in err
    assert "SF_FAST_STOP" not in _flags(homed)


def test_nohup_keeps_sighup_ignored(homed: Sim, spawn: Spawn) -> None:
    """`nohup wsg ...` sets SIGHUP to ignored: wsg must not turn it back on."""
    proc = spawn(["nohup", str(WSG), "--url", homed.url, "monitor", "--json", "--refresh", "0.1",
                             "--duration", "3"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    assert proc.stdout is not None
    assert proc.stdout.readline().startswith("{")
    proc.send_signal(signal.SIGHUP)
    _out, err = _exit(proc, "SIGHUP")
    assert proc.returncode == 0, err  # ran its full --duration
    assert "SF_FAST_STOP" not in _flags(homed)


def test_sigterm_on_a_raw_link_session_announces_the_disconnect(homed: Sim, spawn: Spawn) -> None:
    """`wsg log --subscribe` holds a raw link (not the driver): SIGTERM unwinds its `with Link` too."""
    proc = spawn([str(WSG), "--url", homed.url, "log", "--subscribe", "width", "--json"],
                            stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    assert proc.stdout is not None
    assert proc.stdout.readline().startswith("{")  # the first logged frame: it is connected
    proc.send_signal(signal.SIGTERM)
    _out, err = _exit(proc, "SIGTERM")
    assert proc.returncode == 143, err
    assert "Traceback" not in err
    assert "SF_FAST_STOP" not in _flags(homed)
