"""`wsg send` against `wsg sim`: the packet as composed, the replies (pending then final), error statuses;
and `wsg decode -f` of a live capture of that traffic made with dumpcap/tshark."""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import threading
import time
from collections.abc import Callable
from pathlib import Path

import pytest

from pywsg.protocol import Status, encode_frame

from .conftest import Sim, run_wsg


def _rx(out: str) -> list[str]:
    return [ln for ln in out.splitlines() if ln.startswith("RX  ")]


def test_send_pending_motion_shows_both_replies(sim: Sim) -> None:
    assert sim.wsg("home").code == 0
    r = sim.wsg("send", "preposition", "0", "50.0f", "400.0f")
    assert r.code == 0, r
    assert r.out.splitlines()[0].startswith("TX  AA AA AA 21 09 00 00 00 00 48 42 00 00 C8 43 ")
    rx = _rx(r.out)
    # the manual's 1.3 example, byte for byte: E_CMD_PENDING, then E_SUCCESS
    assert rx[0].startswith("RX  AA AA AA 21 02 00 1A 00 67 CB  PREPOSITION (21h) E_CMD_PENDING")
    assert rx[1].startswith("RX  AA AA AA 21 02 00 00 00 28 04  PREPOSITION (21h) E_SUCCESS")
    assert sim.wsg("width", "--json").json()["width"] == pytest.approx(50.0)


def test_send_unknown_command_is_the_manuals_example(sim: Sim) -> None:
    r = sim.wsg("send", "0x90")
    assert r.code == 1, r
    assert _rx(r.out)[0].startswith("RX  AA AA AA 90 02 00 0E 00 FD 02")  # manual 1.2.2, example 2
    assert "E_CMD_UNKNOWN (14): Unknown command" in r.err


@pytest.mark.parametrize(("args", "status"), [
    (["0x24", '"ac"'], "E_CMD_FORMAT_ERROR"),  # wrong key: "Acknowledge key is incorrect" (000 §3.2.5)
    (["preposition", "0", "50.0f"], "E_CMD_FORMAT_ERROR"),  # payload of the wrong length
    (["stop", "1"], "E_NO_PARAM_EXPECTED"),  # a payload for a command that takes none
    (["homing", "3"], "E_INVALID_PARAMETER"),  # homing direction out of range
    (["get-opening-width", "1", "5u16"], "E_INVALID_PARAMETER"),  # PERIOD_MS below 10
])
def test_send_bad_input_gets_the_spec_status(sim: Sim, args: list[str], status: str) -> None:
    r = sim.wsg("send", "--json", *args)
    assert r.code == 1, r
    data = r.json()
    assert data["ok"] is False and data["status"] == status
    assert data["replies"][-1]["status"] == status
    assert status in r.err


def test_send_auto_update_follow_and_json(homed: Sim) -> None:
    sim = homed
    assert sim.wsg("move", "50", "--speed", "400").code == 0
    r = sim.wsg("send", "--json", "--follow", "0.3", "get-opening-width", "1", "50u16")
    assert r.code == 0, r
    data = r.json()
    assert data["packet"]["hex"] == "AA AA AA 43 03 00 01 32 00 " + data["packet"]["hex"][-5:]
    assert data["packet"]["params"]["period_ms"] == 50
    assert len(data["replies"]) >= 4  # the reply, then auto-update packets every 50 ms
    assert all(x["params"]["width"] == pytest.approx(50.0) for x in data["replies"])
    r = sim.wsg("send", "ack-fast-stop", '"ack"')
    assert r.code == 0 and _rx(r.out)[0].startswith("RX  AA AA AA 24 02 00 00 00 ")


def test_send_over_udp(sim: Sim) -> None:
    r = run_wsg("send", "get-system-info", url=sim.udp_url)
    assert r.code == 0, r
    assert "type=WSG50 (1)" in _rx(r.out)[0]


def test_send_no_gripper_exits_3() -> None:
    r = run_wsg("send", "--timeout", "1", "0x50", url="tcp://127.0.0.1:9")
    assert r.code == 3 and "cannot open" in r.err, r


@pytest.mark.realtime
@pytest.mark.skipif(shutil.which("dumpcap") is None, reason="dumpcap (tshark) not installed")
def test_decode_a_live_capture(homed: Sim, tmp_path: Path) -> None:
    sim = homed
    cap = tmp_path / "live.pcapng"
    # dumpcap writes to a pipe packet by packet (to a file it buffers): the test reads what it wrote so far,
    # so it knows when the last frames are in the capture instead of guessing a pause
    dump = subprocess.Popen(["dumpcap", "-q", "-i", "lo", "-f", f"tcp port {sim.tcp_port}", "-w", "-"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    got = bytearray()

    def pump() -> None:
        assert dump.stdout is not None
        while chunk := os.read(dump.stdout.fileno(), 65536):
            got.extend(chunk)

    reader = threading.Thread(target=pump, daemon=True)
    reader.start()

    def wait_until(cond: Callable[[], bool], what: str) -> None:
        deadline = time.monotonic() + 30
        while not cond():
            if dump.poll() is not None and not got:
                pytest.skip(f"dumpcap cannot capture here: {dump.stderr.read().decode() if dump.stderr else ''}")
            assert time.monotonic() < deadline, f"dumpcap: {what} not written within 30 s"
            time.sleep(0.02)

    wait_until(lambda: len(got) > 0, "the file header")  # written once capturing has started
    unknown_reply = encode_frame(0x90, int(Status.E_CMD_UNKNOWN).to_bytes(2, "little"))
    try:
        assert sim.wsg("move", "40", "--speed", "400").code == 0
        assert sim.wsg("send", "0x90").code == 1
        # the last frames: the 90h reply, then that connection's 07h
        wait_until(lambda: unknown_reply in got and encode_frame(0x07) in got[got.find(unknown_reply):],
                   "the 90h reply and the 07h after it")
    finally:
        dump.send_signal(signal.SIGINT)
        dump.wait(10)
        reader.join(10)
    cap.write_bytes(bytes(got))
    r = run_wsg("decode", "--json", "--port", str(sim.tcp_port), "-f", str(cap))
    assert r.code == 0, r
    frames = json.loads(r.out)
    seq = [(f["direction"], f["command"], f["status"]) for f in frames]
    i = seq.index(("request", "PREPOSITION", None))
    assert seq[i + 1 : i + 3] == [("reply", "PREPOSITION", "E_CMD_PENDING"), ("reply", "PREPOSITION", "E_SUCCESS")]
    assert frames[i]["params"]["width"] == 40.0 and frames[i]["dst"].endswith(f":{sim.tcp_port}")
    assert ("reply", "UNKNOWN_90h", "E_CMD_UNKNOWN") in seq
    assert ("request", "DISCONNECT", None) in seq  # every wsg command announces its disconnect
    r = run_wsg("decode", "-f", str(cap))
    assert "reply PREPOSITION (21h)" in r.out and "status: E_CMD_PENDING (26)" in r.out
