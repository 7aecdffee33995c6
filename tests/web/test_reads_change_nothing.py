"""No read, by any interface, changes what the gripper reports (issue 24 item 4), over real sockets.

On a fresh ``wsg sim``-like stack (TCP command interface, Modbus/TCP, web interface) every GET of the
web interface (each page polls ``/api/identity`` on load and every 5 s), every read command of the
binary protocol (000 chapter 3) and every Modbus read function (FC1–FC4 over the 002 §3 image) leaves
the device as it was: flags (App. B, SF_CMD_FAILURE included), gripper state, width, force, tag,
statistics. Before the fix one ``GET /api/identity`` raised SF_CMD_FAILURE (52h without a tag).
"""

from __future__ import annotations

import dataclasses
import socket
import struct
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest

from pywsg.fieldbus.image import COILS, DISCRETE_INPUTS, INPUT_REGISTERS, OUTPUT_REGISTERS
from pywsg.protocol import Frame, SystemFlag
from pywsg.web.pages import PAGES

from ..device.test_reads_change_nothing import READS
from ..fieldbus.raw_modbus import adu, exchange
from .conftest import LiveSim, client_for, read_frame


@pytest.fixture
def fresh(tmp_path: Path) -> Iterator[LiveSim]:
    with LiveSim(tmp_path) as s:  # its own gripper: no other test's tag, soft limits or failures
        yield s


def _device(sim: LiveSim) -> dict[str, Any]:
    snap = dataclasses.asdict(sim.snapshot())
    for moving_on in ("time", "temperature"):
        snap.pop(moving_on)
    return snap


def _get_paths(web: httpx.Client) -> list[str]:
    """Every GET of the web interface without a path parameter: the API's (from the app's own OpenAPI
    schema), the pages and Help."""
    spec = web.get("/api/openapi.json").json()
    api = [p for p, ops in spec["paths"].items() if "get" in ops and "{" not in p]
    assert "/api/identity" in api and "/api/state" in api and "/api/world" in api
    return sorted(set(api) | set(PAGES) | {"/", "/help", "/api/openapi.json"})


def _read_everything(fresh: LiveSim, web: httpx.Client) -> None:
    before = _device(fresh)
    with socket.create_connection(("127.0.0.1", fresh.tcp.port), timeout=5) as tcp:
        for path in _get_paths(web):
            r = web.get(path)
            assert r.status_code < 500, (path, r.status_code)
            assert _device(fresh) == before, f"GET {path} changed the gripper"
        for cid, payload in READS.items():
            tcp.sendall(Frame(cid, payload).encode())
            assert read_frame(tcp).command_id == cid
            assert _device(fresh) == before, f"{cid:02X}h changed the gripper"
        # Modbus/TCP: coils, discrete inputs, holding registers (the PLC's outputs), input registers
        for fc, count in ((1, COILS), (2, DISCRETE_INPUTS), (3, OUTPUT_REGISTERS), (4, INPUT_REGISTERS)):
            (_, pdu) = exchange(fresh.modbus.port, adu(struct.pack(">BHH", fc, 0, count)))[0]
            assert pdu[0] == fc, pdu.hex()
            assert _device(fresh) == before, f"Modbus FC{fc} changed the gripper"
        tcp.sendall(Frame(0x07, b"").encode())  # announced disconnect: no FAST STOP at teardown
        assert read_frame(tcp).command_id == 0x07


def test_no_read_by_any_interface_changes_the_gripper(fresh: LiveSim) -> None:
    before = _device(fresh)
    assert not before["flags"] & SystemFlag.SF_CMD_FAILURE and before["tag"] is None
    web = client_for(fresh)
    try:
        _read_everything(fresh, web)
    finally:
        web.close()


def test_identity_poll_leaves_no_command_failure(fresh: LiveSim) -> None:
    """The report: one GET /api/identity on a fresh sim with no tag turned SF_CMD_FAILURE on (a PLC saw
    SYSSTATE 00040000h). It answers ``tag: null`` and the flag stays off."""
    with httpx.Client(base_url=fresh.url, timeout=5.0) as web:
        body = web.get("/api/identity").json()
    assert body["tag"] is None and body["model"]
    assert not fresh.snapshot().flags & SystemFlag.SF_CMD_FAILURE
