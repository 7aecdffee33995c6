"""Issue 23 items 9 and 10: the world API refuses what it cannot hold (huge numbers, deep JSON,
numeric strings, a temperature 46h cannot report), with a 422 naming the field, never a 500."""

from __future__ import annotations

import json
import socket
import time
import urllib.error
import urllib.request
from collections.abc import Iterator

import pytest

from pywsg.device import ManualClock, VirtualGripper
from pywsg.device.thermal import MAX_C, MIN_C
from pywsg.protocol import CATALOG, Command, Frame, FrameParser, Status
from pywsg.testing import SimThread
from pywsg.testing.world import WorldError, apply


@pytest.fixture
def sim() -> Iterator[SimThread]:
    with SimThread(web_port=0, tcp_port=0, udp_port=0) as s:
        yield s


def _post(sim: SimThread, path: str, body: bytes) -> tuple[int, dict[str, object], float]:
    url = f"http://127.0.0.1:{sim.sim.grippers[0].web_port}/api/world{path}"
    req = urllib.request.Request(url, data=body, method="POST", headers={"Content-Type": "application/json"})
    t0 = time.perf_counter()
    try:
        with urllib.request.urlopen(req, timeout=20) as resp:
            status, text = int(resp.status), resp.read()
    except urllib.error.HTTPError as exc:
        status, text = exc.code, exc.read()
    return status, json.loads(text), time.perf_counter() - t0


def test_world_api_refuses_huge_numbers_deep_json_and_numeric_strings(sim: SimThread) -> None:
    """A 400-digit number (OverflowError before), 900-deep JSON (RecursionError before) and the string
    "2_2" are each one 422 that names the field; an ordinary request is the baseline for the time."""
    _, _, ordinary = _post(sim, "/heat", b'{"delta_c": 1}')
    status, body, _ = _post(sim, "/heat", b'{"delta_c": 1' + b"0" * 400 + b"}")
    assert status == 422 and "delta_c" in body["errors"], body  # type: ignore[operator]
    status, body, _ = _post(sim, "/part", b'{"width": "2_2"}')
    assert status == 422 and "number" in str(body["errors"]), body
    status, body, _ = _post(sim, "/part", b'{"width": 1e400}')
    assert status == 422, body
    deep = b'{"width": ' + b"[" * 900 + b"]" * 900 + b"}"  # under the 4 KiB body bound
    status, body, deep_time = _post(sim, "/part", deep)
    assert status == 422, body
    assert deep_time < 50 * ordinary + 0.5, (deep_time, ordinary)
    status, body, _ = _post(sim, "/part", b"[" * 2000)  # not JSON at all, and deep
    assert status in (413, 422), body
    assert sim.world.state()["part"] is None  # nothing of that reached the world


def test_world_functions_refuse_strings_and_overflow() -> None:
    g = VirtualGripper("wsg50", clock=ManualClock())
    with pytest.raises(WorldError, match="must be a number"):
        apply(g, "part", {"width": "22"})
    with pytest.raises(WorldError, match="finite"):
        apply(g, "heat", {"delta_c": 10**400})
    with pytest.raises(WorldError, match="finite"):
        apply(g, "fault", {"kind": "finger", "finger": 10**5000})
    # the value itself is never printed whole: a refused 5,000-digit integer stays a short message
    with pytest.raises(WorldError) as info:
        apply(g, "part", {"width": [10**5000]})
    assert len(str(info.value)) < 200


def _temperature(sock: socket.socket) -> tuple[int, float]:
    sock.sendall(Frame(int(Command.GET_TEMPERATURE), b"").encode())
    parser = FrameParser()
    deadline = time.monotonic() + 10
    while time.monotonic() < deadline:
        for ev in parser.feed(sock.recv(4096)):
            if isinstance(ev, Frame) and ev.command_id == Command.GET_TEMPERATURE:
                status, values = CATALOG[Command.GET_TEMPERATURE].decode_reply(ev.payload)
                return int(status), float(values["temperature"]) / 10  # type: ignore[arg-type]  # 0.1 °C
    raise AssertionError("no 46h reply within 10 s")


def test_temperature_stays_in_what_46h_can_report(sim: SimThread) -> None:
    """000 §3.4.7: 46h's temperature is a signed 16-bit count of 0.1 °C. A heat that would leave
    MIN_C..MAX_C is refused (422 naming delta_c) and 46h keeps answering; the old code let 3300 °C
    through and 46h's encoder then dropped the connection."""
    with socket.create_connection(("127.0.0.1", sim.sim.grippers[0].tcp_port), timeout=10) as sock:
        status, start = _temperature(sock)
        assert status == Status.E_SUCCESS and MIN_C <= start <= MAX_C
        for delta in (b"3300", b"1e308", b"-400"):
            code, body, _ = _post(sim, "/heat", b'{"delta_c": ' + delta + b"}")
            assert code == 422 and "delta_c" in body["errors"], (delta, body)  # type: ignore[operator]
        code, _, _ = _post(sim, "/heat", str(MAX_C - start - 1).encode().join((b'{"delta_c": ', b"}")))
        assert code == 200
        status, hot = _temperature(sock)
        assert status == Status.E_SUCCESS and MAX_C - 2 <= hot <= MAX_C
        code, _, _ = _post(sim, "/heat", b'{"delta_c": 5}')  # past MAX_C now
        assert code == 422
        assert _temperature(sock)[0] == Status.E_SUCCESS
        assert sim.world.state()["fast_stop"] is False
