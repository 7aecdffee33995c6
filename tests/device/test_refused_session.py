"""A refused TCP client touches no device state (issue 13 item 8).

docs/fidelity.md ("A refused TCP client"): one TCP client holds the command interface; a second one is
served but every command gets E_ACCESS_DENIED. Its refused commands — and its garbage — must not set the device-wide
SF_CMD_FAILURE ("the last command returned an error", Appendix B), which the controlling client and a
PLC (discrete input 34) read as *their* command having failed.
"""

from __future__ import annotations

import socket
import struct
import time
from collections.abc import Iterator

import pytest

from pywsg.protocol import CATALOG, Frame, FrameParser, Status, SystemFlag

from ..simthread import SimThread, started
from .devrig import Rig

S = Status
SF = SystemFlag


def test_refused_client_does_not_set_cmd_failure(homed: Rig) -> None:
    g = homed.g
    assert not homed.flags() & SF.SF_CMD_FAILURE
    before = g.snapshot()
    second = g.open_session("tcp", peer="127.0.0.1:6000")
    assert second.denied
    for cid, payload in ((0x06, b"x"), (0x21, CATALOG[0x21].encode_request(flags=0, width=10.0, speed=50.0)),
                         (0x23, b""), (0x90, b""), (0x31, b"\x00")):
        assert g.handle_frame(second, Frame(cid, payload))[-1].status == S.E_ACCESS_DENIED
    # bytes with a bad checksum and a SIZE too large from the refused client: answered, nothing changes
    bad_crc = bytearray(Frame(0x06, b"abc").encode())
    bad_crc[-1] ^= 0xFF
    assert [f.status for f in g.feed(second, bytes(bad_crc))] == [S.E_ACCESS_DENIED]
    assert [f.status for f in g.feed(second, b"\xaa\xaa\xaa\x31\xff\x03")] == [S.E_ACCESS_DENIED]
    after = g.snapshot()
    assert not after.flags & SF.SF_CMD_FAILURE
    assert (after.flags, after.gripper_state, after.width, after.fast_stop) == (
        before.flags, before.gripper_state, before.width, before.fast_stop)
    g.close_session(second)
    assert not homed.flags() & SF.SF_CMD_FAILURE and not g.fast_stopped


def test_controller_errors_still_set_cmd_failure(homed: Rig) -> None:
    """Appendix B SF_CMD_FAILURE for the controlling client is unchanged."""
    assert homed.status(0x31, b"\x00") == S.E_NO_PARAM_EXPECTED
    assert homed.flags() & SF.SF_CMD_FAILURE


@pytest.fixture
def sim() -> Iterator[SimThread]:
    """``wsg sim`` on loopback, in a thread (stopped at teardown)."""
    factory = started(SimThread)
    make = next(factory)
    yield make(tcp_port=0, udp_port=0)
    next(factory, None)


def _request(sock: socket.socket, parser: FrameParser, cid: int, payload: bytes = b"") -> Frame:
    sock.sendall(Frame(cid, payload).encode())
    deadline = time.monotonic() + 5
    while time.monotonic() < deadline:
        for ev in parser.feed(sock.recv(4096)):
            if isinstance(ev, Frame) and ev.command_id == cid:
                return ev
    raise TimeoutError(f"no reply to {cid:02X}h")


def test_refused_client_over_real_sockets(sim: SimThread) -> None:
    port = sim.g.tcp_port
    with socket.create_connection(("127.0.0.1", port), timeout=5) as first, \
            socket.create_connection(("127.0.0.1", port), timeout=5) as second:
        p1, p2 = FrameParser(), FrameParser()
        assert _request(first, p1, 0x06, b"1").status == S.E_SUCCESS
        assert _request(second, p2, 0x21, struct.pack("<Bff", 0, 10.0, 50.0)).status == S.E_ACCESS_DENIED
        assert _request(second, p2, 0x06, b"2").status == S.E_ACCESS_DENIED
        state = _request(first, p1, 0x40, struct.pack("<BH", 0, 0))
        assert state.status == S.E_SUCCESS
        assert not struct.unpack("<I", state.params)[0] & SF.SF_CMD_FAILURE
        assert not sim.call(lambda: sim.g.gripper.system_flags()) & SF.SF_CMD_FAILURE
        _request(first, p1, 0x07)
