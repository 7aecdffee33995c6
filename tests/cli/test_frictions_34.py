"""Frictions a new user hit (issue 34 items 4, 6, 7), through the installed ``wsg`` against a ``wsg sim``."""

from __future__ import annotations

import socket
from collections.abc import Iterator

import pytest

from pywsg.testing.host import SimThread

from .conftest import run_wsg


@pytest.fixture(scope="module")
def sim() -> Iterator[SimThread]:
    with SimThread(model="wsg50", tcp_port=0, udp_port=0, udp_reply_port=None) as s:
        yield s


@pytest.mark.parametrize("args", [["move", "20"], ["grip", "20"], ["release", "60"], ["home"]])
def test_no_wait_over_tcp_is_refused_with_the_reason(sim: SimThread, args: list[str]) -> None:
    """000 §3.1.2: the 07h `wsg` sends on exit aborts a running motion, so --no-wait over TCP would lie."""
    r = run_wsg(*args, "--no-wait", url=sim.url)
    assert r.code == 2, r
    assert "07h" in r.err and "000 §3.1.2" in r.err and "UDP" in r.err, r
    assert not sim.call(lambda: sim.gripper.snapshot().moving)  # nothing was sent


def test_no_wait_over_udp_leaves_the_motion_running(sim: SimThread) -> None:
    assert run_wsg("home", url=sim.url).code == 0
    udp = sim.udp_url.split("?")[0] + "?reply_port=0"  # replies to our port: no shared fixed port 1501
    r = run_wsg("move", "5", "--speed", "5", "--no-wait", url=udp)
    assert r.code == 0 and "pending True" in r.out, r
    assert sim.call(lambda: sim.gripper.snapshot().moving)  # no 07h over UDP: it goes on
    assert run_wsg("stop", url=udp).code == 0


@pytest.mark.parametrize("order", ["before", "after"])
def test_global_options_work_on_either_side_of_the_command(order: str) -> None:
    """`wsg --timeout 0.3 width` and `wsg width --timeout 0.3`; `wsg -vv width` and `wsg width -vv`."""
    silent = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)  # a gripper that never answers
    silent.bind(("127.0.0.1", 0))
    try:
        url = f"udp://127.0.0.1:{silent.getsockname()[1]}?reply_port=0"
        opts = ["--timeout", "0.3", "-vv", "--json"]
        argv = [*opts, "width"] if order == "before" else ["width", *opts]
        r = run_wsg("--url", url, *argv)
    finally:
        silent.close()
    assert r.code == 3, r
    assert "no reply within 0.3 s" in r.err, r          # --timeout reached the command
    assert " DEBUG pywsg" in r.err, r                   # -vv reached wsg's logging
    assert r.json()["ok"] is False, r                  # --json reached the command


@pytest.mark.parametrize("order", ["before", "after"])
def test_json_means_the_commands_own_json_on_either_side(order: str) -> None:
    """`wsg --json decode X` and `wsg decode X --json`: decode's own --json (a JSON list) both times."""
    frame = "AA AA AA 06 00 00 97 26"
    r = run_wsg("--json", "decode", frame) if order == "before" else run_wsg("decode", frame, "--json")
    assert r.code == 0 and r.json()[0]["command"] == "LOOP", r


def test_power_fault_error_names_the_fault_not_ack(sim: SimThread) -> None:
    """000 §3.2.5: acknowledging is refused while the fault persists; the error says what to clear first."""
    sim.world.fault("power", True)
    try:
        r = run_wsg("move", "30", url=sim.url)
        assert r.code == 1, r
        assert "power fault" in r.err and "SF_POWER_FAULT" in r.err, r
        assert "run `wsg ack` first" not in r.err, r
        assert "then run `wsg ack`" in r.err, r
    finally:
        sim.world.fault("power", False)
        assert run_wsg("ack", url=sim.url).code == 0
