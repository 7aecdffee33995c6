"""UDP, serial (real pty + pyserial) and CAN (python-can virtual bus) command interfaces."""

from __future__ import annotations

import os
import socket
import time
import uuid
from collections.abc import Callable
from typing import Any

import pytest
import serial

from pywsg.protocol import CATALOG, Frame, FrameParser, Status

from .conftest import AUTO_IDS, SimThread, UdpClient, exercise_catalog

# -- UDP ------------------------------------------------------------------------------------


def test_every_catalog_command_answered_over_udp(sim: SimThread) -> None:
    u = UdpClient(sim.g.udp_port)
    seen = exercise_catalog(u.request, lambda cid: u.reply(cid, timeout=10, skip=AUTO_IDS))
    assert set(seen) == set(CATALOG)
    u.close()


def test_udp_replies_go_to_the_configured_remote_port(sim_factory: Callable[..., SimThread]) -> None:
    inbox = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    inbox.bind(("127.0.0.1", 0))
    inbox.settimeout(3)
    reply_port = inbox.getsockname()[1]
    st = sim_factory(tcp_port=None, udp_port=0, udp_reply_port=reply_port)
    assert st.g.udp_url.endswith(f"?reply_port={reply_port}")
    sender = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sender.bind(("127.0.0.1", 0))
    sender.settimeout(0.3)
    sender.sendto(Frame(0x06, b"where").encode(), ("127.0.0.1", st.g.udp_port))
    data, _ = inbox.recvfrom(2048)
    assert FrameParser().feed(data) == [Frame(0x06, b"\x00\x00where")]
    with pytest.raises(TimeoutError):  # nothing to the sender's own port
        sender.recvfrom(2048)
    sender.close()
    inbox.close()


def test_udp_auto_updates_follow_the_last_client(sim: SimThread) -> None:
    a, b = UdpClient(sim.g.udp_port), UdpClient(sim.g.udp_port)
    assert a.request(0x41, CATALOG[0x41].encode_request(flags=1, period_ms=10)).status == Status.E_SUCCESS
    assert a.receive().command_id == 0x41  # an auto-update packet reaches a
    assert b.request(0x06, b"me now").params == b"me now"
    time.sleep(0.05)
    a.sock.settimeout(0.05)
    try:  # drain what was in flight to a
        while True:
            a.sock.recvfrom(100)
    except TimeoutError:
        pass
    got = [b.receive(timeout=1) for _ in range(3)]
    assert all(f.command_id == 0x41 and f.status == Status.E_SUCCESS for f in got)
    with pytest.raises(TimeoutError):
        a.sock.recvfrom(100)
    b.request(0x41, CATALOG[0x41].encode_request(flags=0, period_ms=10))
    a.close()
    b.close()


def test_udp_truncated_datagram_is_a_format_error(sim: SimThread) -> None:
    u = UdpClient(sim.g.udp_port)
    u.send(Frame(0x06, b"abcdef").encode()[:-3])  # one frame per datagram: the rest never comes
    assert u.reply(0x06, timeout=2).status == Status.E_CMD_FORMAT_ERROR
    u.close()


# -- serial (pty) ---------------------------------------------------------------------------


class SerialClient:
    def __init__(self, path: str) -> None:
        self.port = serial.Serial(path, 115200, timeout=0.05)
        self.parser = FrameParser()
        self.inbox: list[Frame] = []

    def receive(self, timeout: float = 5) -> Frame:
        deadline = time.monotonic() + timeout
        while not self.inbox:
            if time.monotonic() > deadline:
                raise TimeoutError("no frame from the serial port")
            data = self.port.read(4096)
            self.inbox += [e for e in self.parser.feed(data) if isinstance(e, Frame)]
        return self.inbox.pop(0)

    def reply(self, cid: int, timeout: float = 5, skip: tuple[int, ...] = ()) -> Frame:
        while True:
            f = self.receive(timeout)
            if f.command_id == cid:
                return f
            assert f.command_id in skip, f.hex()

    def request(self, cid: int, payload: bytes = b"", timeout: float = 5) -> Frame:
        self.port.write(Frame(cid, payload).encode())
        return self.reply(cid, timeout, skip=AUTO_IDS)

    def close(self) -> None:
        self.port.close()


@pytest.fixture
def serial_sim(sim_factory: Callable[..., SimThread]) -> SimThread:
    return sim_factory(tcp_port=None, udp_port=None, serial="pty")


def test_every_catalog_command_answered_over_a_pty(serial_sim: SimThread) -> None:
    path = serial_sim.g.serial_path
    assert path and os.path.exists(path) and serial_sim.g.serial_url.startswith("serial:///dev/")
    c = SerialClient(path)
    seen = exercise_catalog(c.request, lambda cid: c.reply(cid, timeout=10, skip=AUTO_IDS))
    assert set(seen) == set(CATALOG)
    c.close()


def test_serial_survives_close_and_reopen(serial_sim: SimThread) -> None:
    path = serial_sim.g.serial_path
    for i in range(5):
        c = SerialClient(path)
        c.port.reset_input_buffer()
        payload = f"open {i}".encode()
        assert c.request(0x06, payload).params == payload
        c.close()
    # a subscribed client that vanishes, and a new one that opens the port
    c = SerialClient(path)
    c.request(0x43, CATALOG[0x43].encode_request(flags=1, period_ms=10))
    c.close()
    time.sleep(0.1)
    c = SerialClient(path)
    c.port.reset_input_buffer()
    assert c.request(0x06, b"again").params == b"again"
    c.request(0x43, CATALOG[0x43].encode_request(flags=0, period_ms=10))
    c.close()


def test_serial_line_not_read_stays_bounded(sim_factory: Callable[..., SimThread]) -> None:
    from pywsg.server import Limits

    st = sim_factory(tcp_port=None, udp_port=0, serial="pty", limits=Limits(output_soft=2048, output_hard=8192))
    c = SerialClient(st.g.serial_path)
    for cid in (0x40, 0x41, 0x43, 0x44, 0x45):
        c.port.write(Frame(cid, CATALOG[cid].encode_request(flags=1, period_ms=10)).encode())
    loop = Frame(0x06, bytes(256)).encode()
    for _ in range(40):  # ~270 KB of replies nobody reads: the pty fills, then our queue
        c.port.write(loop * 25)
    time.sleep(0.3)
    srv: Any = st.sim.grippers[0].serial
    assert st.call(lambda: srv.buffered) <= 8192 + 64
    assert st.call(lambda: srv.dropped) > 0
    u = UdpClient(st.g.udp_port)  # the gripper still answers elsewhere
    assert u.request(0x06, b"alive").params == b"alive"
    u.close()
    c.close()


# -- CAN (inferred mapping) -----------------------------------------------------------------


def test_can_virtual_bus_round_trip(sim_factory: Callable[..., SimThread]) -> None:
    can = pytest.importorskip("can")
    channel = f"wsg-{uuid.uuid4().hex[:8]}"
    st = sim_factory(tcp_port=None, udp_port=None, can_channel=channel)
    bus = can.Bus(interface="virtual", channel=channel)
    try:
        def request(cid: int, payload: bytes) -> Frame:
            raw = Frame(cid, payload).encode()
            for i in range(0, len(raw), 8):
                bus.send(can.Message(arbitration_id=0x01, data=raw[i : i + 8], is_extended_id=False))
            parser = FrameParser()
            deadline = time.monotonic() + 5
            while time.monotonic() < deadline:
                msg = bus.recv(0.5)
                if msg is None:
                    continue
                assert msg.arbitration_id == 0x02 and len(msg.data) <= 8
                for ev in parser.feed(bytes(msg.data)):
                    if isinstance(ev, Frame) and ev.command_id == cid:
                        return ev
            raise TimeoutError

        data = bytes(range(40))
        assert request(0x06, data) == Frame(0x06, b"\x00\x00" + data)
        r = request(0x50, b"")
        assert r.status == Status.E_SUCCESS
        assert CATALOG[0x50].decode_reply(r.payload)[1]["type"]
    finally:
        bus.shutdown()
    sg = st.sim.grippers[0]
    assert sg.can.address == f"can://{channel}?interface=virtual&request_id=0x1&reply_id=0x2"  # a client URL
    assert f"gripper 0: CAN      {sg.can.address} (inferred mapping)" in sg.lines()


def test_can_fd_frames_on_the_request_id_are_ignored(sim_factory: Callable[..., SimThread]) -> None:
    """Issue 23 item 16: the mapping is classic CAN (≤ 8 data bytes); a 64-byte CAN FD frame holding a
    whole 50h request is not a request. The classic frames after it are answered as usual."""
    can = pytest.importorskip("can")
    channel = f"wsg-{uuid.uuid4().hex[:8]}"
    st = sim_factory(tcp_port=None, udp_port=None, can_channel=channel)
    bus = can.Bus(interface="virtual", channel=channel, fd=True)
    try:
        fd = Frame(0x50, b"").encode().ljust(64, b"\x00")
        bus.send(can.Message(arbitration_id=0x01, data=fd, is_extended_id=False, is_fd=True))
        raw = Frame(0x06, b"\x01\x02").encode()
        for i in range(0, len(raw), 8):
            bus.send(can.Message(arbitration_id=0x01, data=raw[i : i + 8], is_extended_id=False))
        parser, seen = FrameParser(), []
        deadline = time.monotonic() + 5
        while time.monotonic() < deadline and 0x06 not in seen:
            msg = bus.recv(0.5)
            if msg is not None:
                seen += [ev.command_id for ev in parser.feed(bytes(msg.data)) if isinstance(ev, Frame)]
        assert seen == [0x06], seen  # no 50h reply before the 06h echo: the FD frame was not read
    finally:
        bus.shutdown()
    assert st.sim.grippers[0].can.foreign == 1
