"""What a newcomer hits in the first hour (issue 16): hints in CLI words, local failures said plainly,
one meaning per option, no tracebacks, a warning when the gripper will clamp a target."""

from __future__ import annotations

import json
import socket
import subprocess
import threading
from collections.abc import Iterator

import pytest

from .conftest import WSG, Result, Sim, free_port, run_wsg


@pytest.fixture
def fresh() -> Iterator[Sim]:
    """A sim of its own: these tests need the power-on state (not referenced) or leave FAST STOP behind."""
    s = Sim()
    try:
        yield s
    finally:
        s.stop()


# -- item 2: hints name `wsg` commands ---------------------------------------------------------

def test_not_referenced_hint_names_wsg_home(fresh: Sim) -> None:
    r = fresh.wsg("move", "20")
    assert r.code == 1, r
    assert "E_NOT_INITIALIZED" in r.err and "run `wsg home` first" in r.err
    assert "home()" not in r.err


def test_fast_stop_hint_names_wsg_ack(fresh: Sim) -> None:
    assert fresh.wsg("fast-stop").code == 0
    r = fresh.wsg("home")
    assert r.code == 1, r
    assert "FAST STOP" in r.err and "run `wsg ack` first" in r.err
    assert "acknowledge()" not in r.err
    assert fresh.wsg("ack").code == 0
    assert fresh.wsg("home").code == 0


def test_refusal_because_another_client_holds_tcp_says_so(fresh: Sim) -> None:
    holder = socket.create_connection(("127.0.0.1", fresh.tcp_port), timeout=5)
    try:
        r = fresh.wsg("--json", "width")
        assert r.code == 1, r
        assert "E_ACCESS_DENIED" in r.err and "another client holds" in r.err and "UDP" in r.err
        assert "another client holds" in r.json()["error"]
        # the same gripper over UDP still answers
        assert run_wsg("width", url=fresh.udp_url).code == 0
    finally:
        holder.close()


# -- item 11: local failures -------------------------------------------------------------------

def test_no_reply_is_a_local_timeout_not_a_device_status() -> None:
    port = free_port(socket.SOCK_DGRAM)  # nobody listens there
    r = run_wsg("--json", "width", "--timeout", "0.3", url=f"udp://127.0.0.1:{port}?reply_port=0")
    assert r.code == 3, r
    assert "no reply within 0.3 s (local timeout)" in r.err
    assert "E_TIMEOUT" not in r.err and "WARNING" not in r.err
    info = r.json()
    assert info["local"] == "timeout" and "status" not in info


def test_lost_connection_is_one_error_line_without_a_logging_warning() -> None:
    server = socket.create_server(("127.0.0.1", 0))
    port = server.getsockname()[1]

    def accept_and_drop() -> None:
        conn, _ = server.accept()
        conn.recv(64)  # the request arrives, then the "gripper" goes away
        conn.close()

    t = threading.Thread(target=accept_and_drop, daemon=True)
    t.start()
    try:
        r = run_wsg("width", url=f"tcp://127.0.0.1:{port}")
    finally:
        t.join(5)
        server.close()
    assert r.code == 3, r
    lines = r.err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and "lost" in lines[0], r
    assert "E_IO_ERROR" not in r.err


def test_connection_refused_exits_3() -> None:
    r = run_wsg("width", url=f"tcp://127.0.0.1:{free_port()}")
    assert r.code == 3 and r.err.startswith("error: ") and "Traceback" not in r.err, r


# -- item 10: a target beyond the stroke -------------------------------------------------------

def test_move_beyond_the_stroke_warns_that_the_gripper_clamps(sim: Sim) -> None:
    assert sim.wsg("home").code == 0
    r = sim.wsg("move", "500", "--speed", "400")
    assert r.code == 0, r
    assert "warning: 500 mm is outside the stroke 0..110 mm" in r.err and "clamps the target to 110 mm" in r.err
    assert "width 110.00" in r.out
    ok = sim.wsg("move", "60", "--speed", "400")
    assert ok.code == 0 and "warning" not in ok.err, ok


def test_release_grip_and_speed_beyond_the_limits_warn(sim: Sim) -> None:
    """26h and 25h clamp the width to the stroke (000 §3.2.6, §3.2.7), every motion the speed to the
    53h limits (000 §3.5.4): said on stderr, one line each."""
    assert sim.wsg("home").code == 0
    r = sim.wsg("release", "500", "--speed", "10000")
    assert r.code == 0, r
    assert r.err.splitlines() == [
        "warning: 500 mm is outside the stroke 0..110 mm: the gripper clamps the target to 110 mm",
        "warning: 10000 mm/s is outside the speed limits 5..420 mm/s: the gripper clamps the speed to 420 mm/s"]
    r = sim.wsg("grip", "500", "--speed", "400")  # nothing there: E_CMD_FAILED, but the warning came first
    assert "warning: 500 mm is outside the stroke 0..110 mm: the gripper clamps the part width to 110 mm" in r.err, r
    ok = sim.wsg("release", "--speed", "400")
    assert ok.code == 0 and "warning" not in ok.err, ok


def test_force_limit_and_acceleration_beyond_the_limits_warn(fresh: Sim) -> None:
    """32h clamps to min_force..nominal_force (overdrive_force in overdrive mode; 000 §3.3.3, §3.3.8),
    30h to the acceleration limits (000 §3.3.1)."""
    r = fresh.wsg("force-limit", "0")
    assert r.code == 0 and "force_limit  5.00 N" in r.out, r
    assert "warning: 0 N is outside the force limits 5..80 N: the gripper clamps the force limit to 5 N" in r.err
    r = fresh.wsg("force-limit", "100")
    assert "clamps the force limit to 80 N (`wsg overdrive on` allows up to 120 N)" in r.err, r
    assert fresh.wsg("overdrive", "on").code == 0
    r = fresh.wsg("force-limit", "100")
    assert r.code == 0 and "force_limit  100.00 N" in r.out and "warning" not in r.err, r
    r = fresh.wsg("accel", "99999")
    assert "warning: 99999 mm/s² is outside the acceleration limits 100..5000 mm/s²" in r.err, r
    ok = fresh.wsg("force-limit", "40")
    assert ok.code == 0 and "warning" not in ok.err, ok


# -- item 9: one meaning per option ------------------------------------------------------------

def test_relative_negative_move_needs_no_double_dash(sim: Sim) -> None:
    assert sim.wsg("home").code == 0
    assert sim.wsg("move", "60", "--speed", "400").code == 0
    r = sim.wsg("--json", "move", "--relative", "-5", "--speed", "400")
    assert r.code == 0, r
    assert abs(r.json()["width"] - 55.0) < 0.05


def test_speed_zero_is_refused_and_the_help_says_so() -> None:
    r = run_wsg("move", "20", "--speed", "0")
    assert r.code == 2 and "x>0" in r.err, r
    assert "x>0" in run_wsg("move", "--help").out


def test_timeout_help_does_not_name_an_option_the_command_lacks() -> None:
    help_text = run_wsg("width", "--help").out
    assert "--timeout" in help_text and "--motion-timeout" not in help_text


def test_f_means_file_only() -> None:
    assert "-f, --file" in run_wsg("decode", "--help").out
    log_help = run_wsg("log", "--help").out
    assert "--follow" in log_help and "-f," not in log_help


def test_help_groups_the_subcommands() -> None:
    out = run_wsg("--help").out
    sections = ["Motion:", "State:", "Configuration:", "Tools:"]
    at = [out.index(s) for s in sections]
    assert at == sorted(at)
    motion = out[at[0]:at[1]]
    assert all(f"  {c} " in motion for c in ("home", "move", "grip", "release", "ack"))
    tools = out[at[3]:]
    assert all(f"  {c} " in tools for c in ("send", "decode", "sim", "demo", "plc-demo"))


def test_port_zero_means_any_free_port_and_off_means_off() -> None:
    proc = subprocess.Popen([str(WSG), "sim", "--json", "--no-uvloop", "--tcp-port", "0", "--udp-port", "off",
                             "--serial", "off", "--web-port", "off"], stdout=subprocess.PIPE, text=True)
    try:
        assert proc.stdout is not None
        first = json.loads(proc.stdout.readline())
        assert first["event"] == "interface" and first["kind"] == "tcp"
        port = int(first["url"].rsplit(":", 1)[1])
        assert port != 0
        assert run_wsg("width", url=first["url"]).code == 0
    finally:
        proc.terminate()
        rest = proc.communicate(timeout=15)[0]
    assert [json.loads(line)["event"] for line in rest.splitlines()] == ["stopping"]  # no UDP, no web line


def test_bad_port_word_is_a_usage_error() -> None:
    r = run_wsg("sim", "--tcp-port", "none-such")
    assert r.code == 2 and "0 for any free port, or off" in r.err, r


# -- item 8 and 9: plc-demo and demo -----------------------------------------------------------

def test_plc_demo_model_is_a_choice_and_cycles_must_be_positive() -> None:
    r = run_wsg("plc-demo", "--sim", "--model", "foo")
    assert r.code == 2 and "'wsg50', 'wsg32', 'wsg25', 'wsg70'" in r.err and "Traceback" not in r.err, r
    r = run_wsg("plc-demo", "--sim", "--cycles", "-1")
    assert r.code == 2 and "x>=1" in r.err, r


def test_plc_demo_takes_url_and_exits_3_without_a_connection() -> None:
    port = free_port()
    r = run_wsg("plc-demo", "--url", f"modbus-tcp://127.0.0.1:{port}", "--timeout", "2")
    assert r.code == 3 and f"modbus-tcp://127.0.0.1:{port}" in r.err and "Traceback" not in r.err, r
    old = run_wsg("plc-demo", "--port", str(port), "--timeout", "2")  # deprecated alias, still works
    assert old.code == 3 and "deprecated" in old.err, old


def _assert_one_connection_error(r: Result, url: str) -> None:
    """Exit 3 and a single `error:` line naming the URL: no traceback, no pymodbus log lines."""
    assert r.code == 3, r
    lines = r.err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"error: {url}"), r
    assert "Traceback" not in r.err and ">>>>>" not in r.err and "pymodbus" not in r.err, r


def test_plc_demo_against_a_port_that_never_answers_modbus() -> None:
    """TCP accepted, Modbus never answered (e.g. the gripper's command port by mistake)."""
    with socket.create_server(("127.0.0.1", 0)) as silent:
        url = f"modbus-tcp://127.0.0.1:{silent.getsockname()[1]}"
        r = run_wsg("plc-demo", "--url", url, "--cycles", "1", timeout=60)  # the kernel completes the handshake
        _assert_one_connection_error(r, url)
        assert "no Modbus reply within 3 s" in r.err
        j = run_wsg("--json", "plc-demo", "--url", url, "--cycles", "1", timeout=60)
        assert j.code == 3 and json.loads(j.out.splitlines()[-1])["event"] == "error", j


def test_plc_demo_when_the_gripper_goes_away_mid_cycle() -> None:
    sim = subprocess.Popen([str(WSG), "sim", "--json", "--no-uvloop", "--tcp-port", "off", "--udp-port", "off",
                            "--serial", "off", "--web-port", "off", "--modbus-port", "0"],
                           stdout=subprocess.PIPE, text=True)
    demo: subprocess.Popen[str] | None = None
    try:
        assert sim.stdout is not None
        url = json.loads(sim.stdout.readline())["url"]
        demo = subprocess.Popen([str(WSG), "plc-demo", "--url", url, "--cycles", "1000"], stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, text=True)
        assert demo.stdout is not None
        while "cycle 1 of" not in demo.stdout.readline():  # the demo is talking to the gripper
            assert demo.poll() is None
        sim.kill()
        out, err = demo.communicate(timeout=60)
    finally:
        sim.kill()
        sim.wait()
        if demo is not None and demo.poll() is None:
            demo.kill()
    r = Result(subprocess.CompletedProcess(demo.args, demo.returncode, out, err))
    _assert_one_connection_error(r, url)
    assert "connection lost" in r.err


def test_plc_demo_help_has_no_rst_markup() -> None:
    out = run_wsg("plc-demo", "--help").out
    assert "``" not in out and "--url" in out and "--host" not in out


def test_plc_demo_json() -> None:
    r = run_wsg("plc-demo", "--sim", "--cycles", "1", "--json", timeout=60)
    assert r.code == 0, r
    events = [json.loads(line) for line in r.out.splitlines()]
    assert events[-1]["event"] == "done" and events[-1]["ok"] and events[-1]["cycles"] == 1
    assert any(e["event"] == "step" for e in events)


def test_demo_with_a_port_taken_is_one_clear_error_not_a_traceback() -> None:
    with socket.create_server(("127.0.0.1", 0)) as blocker:
        port = blocker.getsockname()[1]
        for taken in (["--tcp-port", str(port), "--web-port", "0"], ["--tcp-port", "0", "--web-port", str(port)]):
            r = run_wsg("demo", *taken, "--modbus-port", "0", "--exit", "--cycles", "1", timeout=60)
            assert r.code == 3, r
            assert "Traceback" not in r.err and "error:" in r.err and "any free" in r.err, r
            assert len(r.err.strip().splitlines()) <= 3, r
