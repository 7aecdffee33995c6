"""Fixtures for the transport tests: a SimServer running in a background thread with its own event
loop, and small blocking clients (raw sockets, pyserial) as an unmodified WSG client would use."""

from __future__ import annotations

import socket
import struct
import threading
import time
from collections.abc import Callable, Iterator
from typing import Any

import pytest

from pywsg.protocol import CATALOG, Frame, FrameParser, Kind, Status

from ..simthread import SimThread, started


@pytest.fixture
def sim_factory() -> Iterator[Callable[..., SimThread]]:
    yield from started(SimThread)


@pytest.fixture
def sim(sim_factory: Callable[..., SimThread]) -> SimThread:
    return sim_factory(tcp_port=0, udp_port=0)


# -- clients --------------------------------------------------------------------------------


class _FrameClient:
    """What the raw TCP and UDP test clients share: waiting for a reply by ID, request, close."""

    sock: socket.socket

    def receive(self, timeout: float = 5) -> Frame:
        raise NotImplementedError

    def send(self, data: bytes) -> None:
        raise NotImplementedError

    def reply(self, command_id: int, timeout: float = 5, skip: tuple[int, ...] = ()) -> Frame:
        """The next frame with ``command_id`` (other IDs in ``skip`` are dropped, others fail)."""
        while True:
            f = self.receive(timeout)
            if f.command_id == command_id:
                return f
            assert f.command_id in skip, f"unexpected frame {f.hex()} while waiting for {command_id:02X}h"

    def request(self, command_id: int, payload: bytes = b"", timeout: float = 5) -> Frame:
        self.send(Frame(command_id, payload).encode())
        return self.reply(command_id, timeout, skip=AUTO_IDS)

    def close(self) -> None:
        self.sock.close()


class TcpClient(_FrameClient):
    """A blocking raw-socket WSG client."""

    def __init__(self, port: int, host: str = "127.0.0.1", rcvbuf: int | None = None) -> None:
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        if rcvbuf:
            self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, rcvbuf)
        self.sock.connect((host, port))
        self.sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self.sock.settimeout(5)
        self.parser = FrameParser()
        self.inbox: list[Frame] = []

    def send(self, data: bytes) -> None:
        self.sock.sendall(data)

    def receive(self, timeout: float = 5) -> Frame:
        """The next frame from the device."""
        deadline = time.monotonic() + timeout
        while not self.inbox:
            self.sock.settimeout(max(deadline - time.monotonic(), 0.001))
            data = self.sock.recv(65536)
            if not data:
                raise ConnectionError("closed by the device")
            self.inbox += [e for e in self.parser.feed(data) if isinstance(e, Frame)]
        return self.inbox.pop(0)


class UdpClient(_FrameClient):
    """A blocking UDP client; receives on its own socket (reply to the sender's port)."""

    def __init__(self, port: int, host: str = "127.0.0.1") -> None:
        self.addr = (host, port)
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", 0))
        self.sock.settimeout(5)
        self.inbox: list[Frame] = []

    def send(self, data: bytes) -> None:
        self.sock.sendto(data, self.addr)

    def receive(self, timeout: float = 5) -> Frame:
        if self.inbox:
            return self.inbox.pop(0)
        self.sock.settimeout(timeout)
        data, _ = self.sock.recvfrom(65536)
        frames = [e for e in FrameParser().feed(data) if isinstance(e, Frame)]
        assert len(frames) == 1, f"one frame per datagram expected, got {data.hex()}"
        return frames[0]



AUTO_IDS = tuple(cid for cid, spec in CATALOG.items() if spec.auto_update)


def sample_request(command_id: int) -> bytes:
    """A valid request payload for every catalog command (gentle values)."""
    spec = CATALOG[command_id]
    special: dict[int, dict[str, Any]] = {
        0x06: {"data": b"\x01\x02loop"},
        0x20: {"direction": 0},
        0x21: {"flags": 0, "width": 60.0, "speed": 100.0},
        0x24: {"key": "ack"},
        0x25: {"width": 20.0, "speed": 100.0},
        0x26: {"width": 80.0, "speed": 100.0},
        0x30: {"acceleration": 500.0},
        0x32: {"force": 40.0},
        0x34: {"minus": 1.0, "plus": 100.0},
        0x51: {"tag": "cell-7"},
        0x62: {"power": 0},
        0x72: {"power": 0},
    }
    values: dict[str, Any] = dict(special.get(command_id, {}))
    for f in spec.request:
        values.setdefault(f.name, 0.0 if f.type == "f32" else (b"" if f.variable else 0))
    if spec.auto_update:
        values["flags"] = 0
        values["period_ms"] = 0
    return spec.encode_request(values)


def exercise_catalog(request: Callable[[int, bytes], Frame], final: Callable[[int], Frame]) -> dict[int, Any]:
    """Send every command of the catalog; check each answer's ID, status and reply layout.

    Motions get their final frame before the next command. Returns {id: status}.
    """
    seen: dict[int, Any] = {}
    for cid, spec in CATALOG.items():
        reply = request(cid, sample_request(cid))
        assert reply.command_id == cid
        status = reply.status
        allowed = set(spec.statuses) | {Status.E_CMD_PENDING, Status.E_ACCESS_DENIED, Status.E_NOT_AVAILABLE}
        assert status in allowed, f"{spec.label}: {status!r}"
        if status == Status.E_SUCCESS and spec.reply:
            spec.decode_reply(reply.payload)  # raises if the layout is wrong
        if status == Status.E_CMD_PENDING:
            assert spec.kind in (Kind.PENDING, Kind.PENDING_WHEN_ON)
            done = final(cid)
            assert done.status != Status.E_CMD_PENDING
        seen[cid] = status
    assert seen[0x06] == Status.E_SUCCESS
    return seen


def loop_frame(data: bytes) -> bytes:
    return Frame(0x06, data).encode()


def bad_crc(frame: bytes) -> bytes:
    crc = struct.unpack("<H", frame[-2:])[0] ^ 0x5A5A
    return frame[:-2] + struct.pack("<H", crc)


class GoodClient(threading.Thread):
    """A well-behaved client running Loop requests with random payloads and checking every answer."""

    def __init__(self, make: Callable[[], Any]) -> None:
        super().__init__(daemon=True)
        self.make = make
        self.ok = 0
        self.errors: list[str] = []
        self._stop_evt = threading.Event()

    def run(self) -> None:
        import os

        client = self.make()
        try:
            while not self._stop_evt.is_set():
                data = os.urandom(1 + self.ok % 64)
                try:
                    r = client.request(0x06, data)
                except Exception as exc:
                    self.errors.append(repr(exc))
                    return
                if r.status != Status.E_SUCCESS or r.params != data:
                    self.errors.append(f"wrong answer {r.hex()}")
                    return
                self.ok += 1
                time.sleep(0.001)
        finally:
            if isinstance(client, TcpClient):
                try:
                    client.request(0x07)  # announced: its close raises no FAST STOP
                except Exception:
                    pass
            client.close()

    def check(self, at_least: int = 1) -> int:
        """Let it reach ``at_least`` answers, stop it, assert every answer was right."""
        deadline = time.monotonic() + 10
        while self.ok < at_least and not self.errors and self.is_alive() and time.monotonic() < deadline:
            time.sleep(0.005)
        self._stop_evt.set()
        self.join(10)
        assert not self.errors, self.errors
        assert self.ok >= at_least, f"good client got only {self.ok} answers"
        return self.ok
