"""Settings file errors of ``wsg sim``: one line naming the file and what to do, exit code 1, no
traceback (docs/sim.md, "Settings file"). Run as a user runs it: a real ``wsg sim`` process."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from pywsg.device import Settings

from ..ports import free_base
from .test_cli_sim import start_sim, stop

SIM = [sys.executable, "-c", "from pywsg.cli.main import main; main()", "sim"]
OFF = ["--udp-port", "0", "--serial", "off", "--web-port", "0"]


def run_sim_once(settings: Path) -> subprocess.CompletedProcess[str]:
    port = free_base(1)
    return subprocess.run([*SIM, "--tcp-port", str(port), *OFF, "--settings", str(settings)],
                          capture_output=True, text=True, timeout=30)


def assert_one_line_error(r: subprocess.CompletedProcess[str], path: Path, *words: str) -> None:
    assert r.returncode == 1, (r.returncode, r.stdout, r.stderr)
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1, r.stderr
    assert "Traceback" not in r.stderr
    assert str(path) in lines[0]
    for w in words:
        assert w in lines[0], lines[0]


@pytest.mark.parametrize("name, text, words", [
    ("corrupt", '{"crc_check": tru', ("corrupt settings file", "move it away")),
    ("huge integer", '{"serial_number": ' + "9" * 5000 + "}", ("digits", "move it away")),
    ("deep nesting", "[" * 30000 + "]" * 30000, ("nested too deeply", "move it away")),
    ("not a settings file", "0" * 100_000, ("not a settings file",)),
    ("not UTF-8", "\udcff", ("not UTF-8",)),
    ("invalid value", '{"homing_direction": 7}', ("homing_direction", "move it away")),
])
def test_bad_settings_file_is_one_line(tmp_path: Path, name: str, text: str, words: tuple[str, ...]) -> None:
    path = tmp_path / "wsg.json"
    path.write_bytes(text.encode("utf-8", "surrogateescape"))
    r = run_sim_once(path)
    assert_one_line_error(r, path, *words)
    assert path.read_bytes() == text.encode("utf-8", "surrogateescape")  # never overwritten


def test_failed_save_at_sigterm_is_one_line(tmp_path: Path) -> None:
    path = tmp_path / "wsg.json"
    port = free_base(1)
    proc, _ = start_sim("--tcp-port", str(port), *OFF, "--settings", str(path), lines=1)
    path.mkdir()  # the save's rename now fails (also as root, unlike a read-only directory)
    rc, _ = stop(proc)
    err = proc.stderr.read() if proc.stderr else ""
    r = subprocess.CompletedProcess(proc.args, rc, "", err.replace("stopping\n", ""))
    assert_one_line_error(r, path, "cannot save settings", "writable directory")
    assert not list(tmp_path.glob(".wsg.json.*.tmp"))


def test_temporaries_of_a_killed_save_are_removed_at_next_start(tmp_path: Path) -> None:
    path = tmp_path / "wsg.json"
    Settings(homing_direction=2).save(path)
    leftovers = [tmp_path / ".wsg.json.abc123.tmp", tmp_path / ".wsg.json.x.tmp"]
    for tmp in leftovers:  # what SIGKILL between mkstemp and rename leaves
        tmp.write_text('{"crc_check": fal')
    other = tmp_path / ".other.json.abc.tmp"
    other.write_text("not ours")
    port = free_base(1)
    proc, _ = start_sim("--tcp-port", str(port), *OFF, "--settings", str(path), lines=1)
    assert not any(t.exists() for t in leftovers)
    assert other.exists()
    rc, _ = stop(proc)
    assert rc == 0
    assert json.loads(path.read_text())["homing_direction"] == 2


def test_a_save_killed_with_sigkill_leaves_nothing_after_the_next_start(tmp_path: Path) -> None:
    """A real SIGKILL during a (slowed) save: the file stays whole and the temporary goes next start."""
    path = tmp_path / "wsg.json"
    Settings().save(path)
    code = (
        "import os, time, pywsg.device.settings as m\n"
        ""
        "def slow(fd):\n"
        "    print('saving', flush=True); time.sleep(30)\n"
        "m.os.fsync = slow\n"
        f"m.Settings(homing_direction=2).save({str(path)!r})\n"
    )
    proc = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True)
    assert proc.stdout is not None and proc.stdout.readline().strip() == "saving"
    proc.kill()
    proc.wait(10)
    assert list(tmp_path.glob(".wsg.json.*.tmp"))
    assert Settings.load(path) == Settings()  # the old file is whole
    assert not list(tmp_path.glob(".wsg.json.*.tmp"))
