"""``wsg sim --profibus pty`` as a user runs it: a real process and a real DP master on its pty."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

from .pbmaster import dp_master, run_until, start

pytestmark = pytest.mark.realtime


@pytest.fixture
def procs() -> Iterator[list[subprocess.Popen[str]]]:
    running: list[subprocess.Popen[str]] = []
    yield running
    for p in running:
        if p.poll() is None:
            p.kill()
        p.wait(10)


def _sim(procs: list[subprocess.Popen[str]], *args: str) -> tuple[subprocess.Popen[str], str]:
    proc = subprocess.Popen(
        [sys.executable, "-c", "from pywsg.cli.main import main; main()", "sim", "--tcp-port", "off",
         "--udp-port", "off", "--serial", "off", "--web-port", "off", "--profibus", "pty", *args],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=dict(os.environ, PYTHONUNBUFFERED="1"))
    procs.append(proc)
    assert proc.stdout is not None
    line = proc.stdout.readline().strip()
    assert line, f"wsg sim printed nothing: {proc.stderr.read() if proc.stderr else ''}"
    return proc, line


def test_sim_prints_its_profibus_line_and_serves_a_master(procs: list[subprocess.Popen[str]]) -> None:
    proc, line = _sim(procs, "--profibus-address", "9")
    assert line.startswith("gripper 0: PROFIBUS profibus:///dev/") and line.endswith("?address=9&baudrate=19200")
    path = line.split("profibus://", 1)[1].split("?", 1)[0]
    with dp_master(path, address=9) as (master, desc):
        start(master, desc)
        inputs = run_until(master, desc, lambda d: d is not None, "Data_Exch with `wsg sim`")
        assert inputs is not None and len(inputs) == 12
    proc.send_signal(signal.SIGTERM)
    assert proc.wait(10) == 0


def test_sim_json_line_and_a_refused_baud_rate(procs: list[subprocess.Popen[str]]) -> None:
    _, line = _sim(procs, "--json")
    data = json.loads(line)
    assert data["kind"] == "profibus" and data["url"].startswith("profibus:///dev/")
    bad = subprocess.run(
        [sys.executable, "-c", "from pywsg.cli.main import main; main()", "sim", "--profibus", "pty",
         "--profibus-baudrate", "12000000"], capture_output=True, text=True, timeout=30)
    assert bad.returncode == 2 and "WEIS5555.gsd" in bad.stderr and "Traceback" not in bad.stderr
    auto = subprocess.run(
        [sys.executable, "-c", "from pywsg.cli.main import main; main()", "sim", "--profibus", "pty",
         "--profibus-baudrate", "auto"], capture_output=True, text=True, timeout=30)
    assert auto.returncode == 2 and "a pty has no bit timing" in auto.stderr


def test_station_address_comes_from_the_stored_interface_settings(
        procs: list[subprocess.Popen[str]], tmp_path: Path) -> None:
    """Settings → Command Interface stores profibus_address beside the settings file (002 §2.1.2)."""
    (tmp_path / "s.interface.json").write_text(json.dumps({"profibus_address": 23}))
    _, line = _sim(procs, "--settings", str(tmp_path / "s.json"))
    assert "?address=23&" in line


def test_a_missing_serial_device_is_one_clear_line() -> None:
    bad = subprocess.run(
        [sys.executable, "-c", "from pywsg.cli.main import main; main()", "sim", "--tcp-port", "0", "--udp-port",
         "0", "--serial", "off", "--web-port", "off", "--profibus", "/dev/no-such-rs485"],
        capture_output=True, text=True, timeout=30)
    assert bad.returncode == 1 and "Traceback" not in bad.stderr
    lines = bad.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].endswith(
        "gripper 0: cannot open PROFIBUS line /dev/no-such-rs485: No such file or directory "
        "(--profibus pty for a new pseudo-terminal)"), bad.stderr
