"""Command-line frictions a newcomer meets: where options go, typos, a port in use, time stamps, -v.

Each test runs the installed ``wsg`` as a subprocess against real sockets on 127.0.0.1.
"""

from __future__ import annotations

import json
import re
import signal
import socket
import subprocess
import time
from pathlib import Path

import pytest

from .conftest import WSG, Sim, free_port, run_wsg

README = Path(__file__).resolve().parents[2] / "README.md"


def test_url_works_on_either_side_of_the_subcommand(sim: Sim) -> None:
    """`--url` after the subcommand, like `--json` and `--log` (was "No such option '--url'")."""
    r = run_wsg("width", "--url", sim.url, "--json")
    assert r.code == 0, r
    assert "width" in r.json()
    # the subcommand's --url wins over the group's (here a port nobody listens on)
    dead = f"tcp://127.0.0.1:{free_port()}"
    r = run_wsg("--url", sim.url, "width", "--url", dead)
    assert r.code == 3 and dead in r.err, r


def test_monitor_on_udp_beside_commands_on_tcp(sim: Sim) -> None:
    """The README's advice: `wsg monitor --url udp://…` watches while commands on TCP still work."""
    text = README.read_text()
    assert "wsg monitor --url udp://" in text and "one TCP client at a time" in text
    mon = subprocess.Popen([str(WSG), "monitor", "--url", sim.udp_url, "--json", "--duration", "3",
                            "--refresh", "0.1"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert mon.stdout is not None
        first = mon.stdout.readline()  # the monitor is watching
        assert "width" in json.loads(first), first
        r = run_wsg("width", url=sim.url)  # TCP is free: the monitor is on UDP
        assert r.code == 0, r
        assert mon.wait(20) == 0, mon.stderr.read() if mon.stderr else ""
    finally:
        if mon.poll() is None:
            mon.kill()
        mon.wait()


@pytest.mark.parametrize(("args", "hint"), [
    (["move", "30", "--sped", "50"], "No such option '--sped'. Did you mean '--speed'?"),
    (["grip", "20", "--forse", "30"], "Did you mean '--force'?"),
    (["mvoe"], "No such command 'mvoe'. Did you mean 'move'?"),
    (["world", "heat", "--dleta", "3"], "No such option '--dleta'"),
    (["world", "haet", "3"], "No such command 'haet'. Did you mean 'heat'?"),
])
def test_typos_get_a_suggestion(args: list[str], hint: str) -> None:
    r = run_wsg(*args, url=f"tcp://127.0.0.1:{free_port()}")
    assert r.code == 2, r
    assert hint in r.err, r
    assert "unexpected extra arguments" not in r.err


def test_negative_numbers_are_still_arguments() -> None:
    """`wsg move -5 --relative` is a move, not a typo: it gets as far as connecting."""
    url = f"tcp://127.0.0.1:{free_port()}"
    r = run_wsg("move", "-5", "--relative", url=url)
    assert r.code == 3 and "cannot connect" in r.err, r


@pytest.mark.parametrize(("option", "extra"), [
    ("--web-port", ["--tcp-port", "0"]),
    ("--tcp-port", ["--web-port", "off"]),
])
def test_port_in_use_names_the_port_and_the_way_out(option: str, extra: list[str]) -> None:
    with socket.create_server(("127.0.0.1", 0)) as blocker:
        port = blocker.getsockname()[1]
        r = run_wsg("sim", "--no-uvloop", "--udp-port", "off", "--serial", "off", option, str(port), *extra,
                    timeout=30)
    assert r.code == 1, r
    line = r.err.strip()
    assert len(line.splitlines()) == 1 and "Traceback" not in line, r
    assert f"127.0.0.1:{port}" in line and "in use" in line, r
    assert f"{option} 0 for any free port" in line, r


def test_decode_file_prints_the_time_of_day_like_the_log(tmp_path: Path) -> None:
    """`wsg decode -f` shows 19:44:34.052109 like `wsg proxy` and `--log`, not Unix seconds."""
    t = 1_764_100_000.052109
    log = tmp_path / "log.jsonl"
    log.write_text(json.dumps({"time": t, "direction": "tx", "hex": "AA AA AA 20 01 00 00 6F 89"}) + "\n")
    r = run_wsg("decode", "-f", str(log))
    shown = time.strftime("%H:%M:%S", time.localtime(t)) + ".052109"
    assert r.out.splitlines()[0].startswith(shown + " TX"), r
    assert str(int(t)) not in r.out


def test_sim_verbose_lines_are_not_called_warnings() -> None:
    """`wsg sim -v`: informational lines say INFO, never "warning:"."""
    port = free_port()
    proc = subprocess.Popen([str(WSG), "sim", "-v", "--no-uvloop", "--tcp-port", str(port), "--udp-port", "off",
                             "--serial", "off", "--web-port", "off"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert proc.stdout is not None
        banner = proc.stdout.readline()  # "gripper 0: TCP ...": the interface listens
        assert "TCP" in banner, banner
        assert run_wsg("width", url=f"tcp://127.0.0.1:{port}").code == 0
    finally:
        proc.terminate()
        try:
            _, err = proc.communicate(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            _, err = proc.communicate()
    lines = [ln for ln in err.splitlines() if "GET_OPENING_WIDTH" in ln]
    assert lines, err
    assert all(re.search(r"\bINFO\b", ln) and not ln.startswith("warning:") for ln in lines), lines


def _sim_with_settings(path: Path) -> tuple[subprocess.Popen[str], str]:
    port = free_port()
    proc = subprocess.Popen([str(WSG), "sim", "--no-uvloop", "--tcp-port", str(port), "--udp-port", "off", "--serial",
                             "off", "--web-port", "off", "--settings", str(path)],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    assert proc.stdout is not None
    banner = proc.stdout.readline()
    assert "TCP" in banner, banner
    return proc, f"tcp://127.0.0.1:{port}"


def _stop(proc: subprocess.Popen[str]) -> None:
    proc.send_signal(signal.SIGINT)
    try:
        proc.wait(10)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()


def test_device_tag_survives_a_restart_with_settings(tmp_path: Path) -> None:
    """51h's tag is kept in the --settings file: after a restart 52h still answers it."""
    settings = tmp_path / "settings.json"
    proc, url = _sim_with_settings(settings)
    try:
        assert run_wsg("tag", "set", "cell-7", url=url).code == 0
    finally:
        _stop(proc)
    assert json.loads(settings.read_text())["tag"] == "cell-7"
    proc, url = _sim_with_settings(settings)
    try:
        r = run_wsg("tag", "--json", url=url)
        assert r.code == 0 and r.json() == {"tag": "cell-7"}, r
    finally:
        _stop(proc)
