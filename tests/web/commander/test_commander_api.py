"""``wsg commander``'s server against ``wsg sim`` over TCP, UDP and a serial pty (000 §2), without a browser.

The Custom Command Editor's packet reaches the sim byte for byte; predefined commands run through the
driver in the manual's units; the state streams live while a motion runs and Stop ends it (000
§3.2.3); the saved log reads back with the project's readers; closing the page announces the
disconnect (07h, 000 §3.1.2) so the gripper does not FAST STOP (000 §1.4.2); a lost connection shows
at once; the web interface's protections (CSRF, Host check, login off loopback) hold.
"""

from __future__ import annotations

import time
import uuid
from collections.abc import Iterator
from pathlib import Path

import pytest
from click.testing import CliRunner
from websockets.sync.client import connect as ws_connect

from pywsg.capture.reader import frames_from_capture, frames_from_jsonl
from pywsg.cli.main import cli
from pywsg.testing.host import SimThread

from ..conftest import wait_for
from .harness import Cmdr, WireTap


@pytest.fixture(scope="module")
def sim() -> Iterator[SimThread]:
    channel = f"cmdr-{uuid.uuid4().hex[:8]}"  # python-can's virtual channels are process-global
    with SimThread(model="wsg50", tcp_port=0, udp_port=0, udp_reply_port=None, can_channel=channel) as s:
        yield s


def udp_url(sim: SimThread) -> str:
    """The sim's UDP address, replies to our own port (no fixed local port 1501 that parallel tests share)."""
    return sim.udp_url.split("?")[0] + "?reply_port=0"


@pytest.fixture(scope="module")
def tap(sim: SimThread) -> WireTap:
    return WireTap(sim)


@pytest.fixture(scope="module")
def cmdr() -> Iterator[Cmdr]:
    with Cmdr() as c:
        yield c


def _final(cmdr: Cmdr, command: str, after: int = 0, timeout: float = 20.0) -> dict[str, object]:
    found: list[dict[str, object]] = []

    def done() -> bool:
        found[:] = [r for r in cmdr.state()["results"]
                    if r["command"] == command and r["final"] and int(r["seq"]) > after]
        return bool(found)

    wait_for(done, timeout)
    return found[-1]


def _last_seq(cmdr: Cmdr) -> int:
    results = cmdr.state()["results"]
    return int(results[-1]["seq"]) if results else 0


@pytest.mark.parametrize("link", ["tcp", "udp", "serial", "can"])
def test_editor_packet_reaches_the_sim_byte_equal(sim: SimThread, tap: WireTap, cmdr: Cmdr, link: str) -> None:
    """000 §2: the packet the editor shows (CRC added) is what the gripper receives, on every link."""
    url = {"tcp": sim.url, "udp": udp_url(sim), "serial": sim.serial_url, "can": sim.g.can.address}[link]
    assert cmdr.connect(url)["status"] == "connected"
    shown = cmdr.http.get("/api/editor", params={"id": "06h", "payload": '"ack" 0x20 -1 150.0f 1000u16'}).json()
    assert shown["ok"], shown
    wire = bytes.fromhex(shown["wire"])
    assert wire[:4] == b"\xaa\xaa\xaa\x06" and wire[6:11] == b"ack \xff"
    tap.clear()
    after = _last_seq(cmdr)
    r = cmdr.http.post("/api/send", json={"id": "06h", "payload": '"ack" 0x20 -1 150.0f 1000u16'})
    assert r.status_code == 200, r.text
    assert r.json()["wire"] == shown["wire"]
    assert _final(cmdr, "LOOP", after)["status"] == "E_SUCCESS"
    assert wire in tap.data, (link, tap.data.hex(" "))
    # the Communication Log has both directions, decoded
    rows = cmdr.http.get("/api/log.jsonl").text.splitlines()
    assert any(f'"hex": "{shown["wire"]}"' in line and '"direction": "tx"' in line for line in rows)
    assert any('"command": "LOOP"' in line and '"direction": "rx"' in line and '"E_SUCCESS"' in line for line in rows)


def test_motion_shows_live_state_and_stop_ends_it(sim: SimThread, cmdr: Cmdr) -> None:
    """Predefined commands in mm and mm/s; auto-update streams show the motion; Stop (22h) aborts it."""
    cmdr.connect(sim.url)
    after = _last_seq(cmdr)
    r = cmdr.http.post("/api/command/home", json={})
    assert r.status_code == 202, r.text
    assert _final(cmdr, "HOMING", after)["status"] == "E_SUCCESS"
    start = cmdr.state()["state"]["width"]
    after = _last_seq(cmdr)
    r = cmdr.http.post("/api/command/move", json={"width": 5, "speed": 10})
    assert r.status_code == 202 and r.json()["status"] == "E_CMD_PENDING", r.text
    wait_for(lambda: cmdr.state()["state"].get("moving") is True, 10)
    wait_for(lambda: abs(cmdr.state()["state"]["width"] - start) > 0.5, 10)  # streamed while it moves
    assert cmdr.state()["state"]["gripper_state"] == "POSITIONING"
    r = cmdr.http.post("/api/command/stop", json={})
    assert r.status_code == 200 and r.json()["status"] == "E_SUCCESS", r.text
    assert _final(cmdr, "PREPOSITION", after)["status"] == "E_CMD_ABORTED"
    wait_for(lambda: cmdr.state()["state"].get("moving") is False, 10)


def test_predefined_command_refuses_bad_values_by_field(sim: SimThread, cmdr: Cmdr) -> None:
    cmdr.connect(sim.url)
    r = cmdr.http.post("/api/command/move", json={"width": "wide", "speed": 10})
    assert r.status_code == 422 and r.json()["errors"] == {"width": "a number in mm"}, r.text
    r = cmdr.http.post("/api/command/set_acceleration", json={"acceleration": 150})
    assert r.status_code == 200 and r.json()["status"] == "E_SUCCESS", r.text
    r = cmdr.http.post("/api/command/get_acceleration", json={})
    assert r.json()["values"] == pytest.approx(150.0), r.text


def test_editor_error_names_the_token_and_nothing_is_sent(cmdr: Cmdr) -> None:
    text = "1 2 0x1FF 3"
    got = cmdr.http.get("/api/editor", params={"id": "0x06", "payload": text}).json()
    assert not got["ok"] and got["field"] == "payload"
    assert text[got["start"]:got["end"]] == "0x1FF", got
    got = cmdr.http.get("/api/editor", params={"id": "frobnicate", "payload": ""}).json()
    assert not got["ok"] and got["field"] == "id" and "unknown command" in got["error"]
    r = cmdr.http.post("/api/send", json={"id": "0x06", "payload": text})
    assert r.status_code == 422 and (r.json()["start"], r.json()["end"]) == (4, 9), r.text


def test_saved_log_reads_back_as_jsonl_and_pcapng(sim: SimThread, cmdr: Cmdr, tmp_path: Path) -> None:
    """The two files `wsg decode -f` and `wsg replay` read hold the frames as sent and received."""
    cmdr.connect(sim.url)
    assert cmdr.http.post("/api/log/clear").status_code == 200  # this test's frames only
    after = _last_seq(cmdr)
    cmdr.http.post("/api/command/width", json={})
    cmdr.http.post("/api/send", json={"id": "loop", "payload": "1 2 3"})
    _final(cmdr, "LOOP", after)
    jsonl, pcapng = tmp_path / "log.jsonl", tmp_path / "log.pcapng"
    jsonl.write_text(cmdr.http.get("/api/log.jsonl").text)
    r = cmdr.http.get("/api/log.pcapng")
    assert r.headers["content-disposition"].startswith("attachment")
    pcapng.write_bytes(r.content)
    logged = [(f.direction, f.decoded.raw) for f in frames_from_jsonl(jsonl)]
    captured = [("tx" if f.decoded.direction == "request" else "rx", f.decoded.raw)
                for f in frames_from_capture(pcapng)]
    assert logged == captured and len(logged) >= 4
    assert ("tx", bytes.fromhex("AA AA AA 06 03 00 01 02 03") + logged[-2][1][-2:]) in logged
    for path in (jsonl, pcapng):
        out = CliRunner().invoke(cli, ["decode", "-f", str(path)])
        assert out.exit_code == 0 and "LOOP" in out.output, out.output
    cmdr.http.post("/api/disconnect")  # one TCP client at a time: the replay's turn
    report = sim.replay(pcapng)
    assert report.matched and report.steps == 2, [d.line() for d in report.differences]
    # the recording ends without 07h, so the replay's TCP close FAST STOPs the sim (000 §1.4.2), once the
    # sim has seen the close: wait for it, then clear it for the next test
    wait_for(lambda: sim.call(lambda: sim.gripper.snapshot().fast_stop), 10)
    sim.call(sim.gripper.acknowledge_fast_stop)


def test_closing_the_page_announces_the_disconnect(sim: SimThread, tap: WireTap, cmdr: Cmdr) -> None:
    """000 §3.1.2 / §1.4.2: the last page gone, the Commander sends 07h and the gripper stays out of FAST STOP."""
    assert not sim.call(lambda: sim.gripper.snapshot().fast_stop)
    cmdr.connect(sim.url)
    cookie = "; ".join(f"{k}={v}" for k, v in cmdr.http.cookies.items())
    with ws_connect(cmdr.url.replace("http", "ws") + "/ws", additional_headers={"Cookie": cookie}) as ws:
        assert '"type": "update"' in ws.recv(timeout=10)
        tap.clear()
    wait_for(lambda: cmdr.state()["connection"]["status"] == "disconnected", 10)
    assert "page was closed" in cmdr.state()["connection"]["reason"]
    assert bytes.fromhex("AA AA AA 07 00 00") in tap.data
    time.sleep(0.2)  # the sim sees the TCP close after 07h
    assert not sim.call(lambda: sim.gripper.snapshot().fast_stop)


def test_lost_connection_shows_at_once(sim: SimThread, cmdr: Cmdr) -> None:
    cmdr.connect(sim.url)
    sim.world.disconnect()  # the gripper closes the TCP connection (and FAST STOPs: no 07h came)
    try:
        wait_for(lambda: cmdr.state()["connection"]["status"] == "lost", 5)
        assert "lost" in cmdr.state()["connection"]["reason"]
        r = cmdr.http.post("/api/command/width", json={})
        assert r.status_code == 409 and "not connected" in r.json()["detail"]
    finally:
        sim.call(sim.gripper.acknowledge_fast_stop)


def test_a_silent_gripper_shows_over_udp_and_clears_when_it_answers(sim: SimThread, cmdr: Cmdr) -> None:
    """UDP has no connection to lose: a command without a reply marks the gripper silent, a reply clears it."""
    cmdr.connect(udp_url(sim))
    sim.world.net("silent")
    try:
        r = cmdr.http.post("/api/command/width", json={})
        assert r.json()["status"] == "E_TIMEOUT", r.text
        conn = cmdr.state()["connection"]
        assert conn["status"] == "silent" and "no answer" in conn["reason"], conn
    finally:
        sim.world.net("silent", False)
    # the driver takes the first reply after a local timeout for the late answer to the request that
    # timed out (it cannot tell), so the first command may time out too; its reply clears "silent"
    cmdr.http.post("/api/command/width", json={})
    wait_for(lambda: cmdr.state()["connection"]["status"] == "connected", 10)
    r = cmdr.http.post("/api/command/width", json={})
    assert r.json()["status"] == "E_SUCCESS", r.text


def test_serial_port_picker_lists_pyserial_ports(cmdr: Cmdr, monkeypatch: pytest.MonkeyPatch) -> None:
    from serial.tools import list_ports, list_ports_common

    port = list_ports_common.ListPortInfo("/dev/ttyUSB7")
    port.description = "WSG 50 RS232 adapter"
    monkeypatch.setattr(list_ports, "comports", lambda: [port])
    assert cmdr.http.get("/api/ports").json() == {"ports": [{"device": "/dev/ttyUSB7",
                                                             "description": "WSG 50 RS232 adapter"}]}


def test_web_interface_protections_hold(cmdr: Cmdr) -> None:
    """CSRF token on every change, Host check against DNS rebinding, login off loopback (docs/web.md)."""
    import httpx

    bare = httpx.post(cmdr.url + "/api/disconnect")
    assert bare.status_code == 403 and "CSRF" in bare.json()["detail"]
    assert httpx.get(cmdr.url + "/", headers={"Host": "rebind.example"}).status_code == 400
    page = httpx.get(cmdr.url + "/")
    assert "default-src 'self'" in page.headers["content-security-policy"]
    assert page.headers["x-frame-options"] == "DENY"
    with Cmdr(password="pw", host="0.0.0.0") as remote:  # a non-loopback bind (reached over 127.0.0.1)
        r = httpx.get(remote.url + "/", follow_redirects=False)
        assert r.status_code == 303 and r.headers["location"].startswith("/login")
        assert httpx.get(remote.url + "/api/state").status_code == 401
        form = httpx.get(remote.url + "/login")
        assert 'type="password"' in form.text
