"""Blocking transports of :class:`~pywsg.client.Gripper`: plain sockets and a serial fd.

``recv(timeout)`` returns the bytes read, ``b""`` when ``timeout`` s passed without data, and
raises ``ConnectionError`` when the other side is gone.

Sockets stay in blocking mode and the kernel bounds each wait (``SO_RCVTIMEO`` / ``SO_SNDTIMEO``):
a Python-level socket timeout costs a ``poll()`` before every ``send``/``recv`` and an ``ioctl``
whenever it changes, about 5 µs per round trip on loopback. The receive timeout is set again only
when the wait asked for is longer than the one set, or more than ``_TIMEOUT_SLACK`` shorter
(so a wait may end up to that much late, never early).
"""

from __future__ import annotations

import os
import select
import socket
import struct
import sys
from typing import Any

from ..url import Endpoint

_RECV_SIZE = 4096  # a frame is at most 1032 bytes; the parser joins partial reads
_DGRAM_SIZE = 65536
_TIMEOUT_SLACK = 0.002  # s
_KERNEL_TIMEOUTS = sys.platform != "win32" and hasattr(socket, "SO_RCVTIMEO")


def _timeval(seconds: float) -> bytes:
    us = max(1, round(seconds * 1e6))  # 0 would mean "wait forever"
    return struct.pack("@ll", us // 1_000_000, us % 1_000_000)


class _SocketWaits:
    """Per-wait timeouts on a blocking socket, set in the kernel only when they change noticeably."""

    sock: socket.socket

    def _init_waits(self, send_timeout: float) -> None:
        self._rcv = -1.0
        if _KERNEL_TIMEOUTS:
            self.sock.settimeout(None)
            self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_SNDTIMEO, _timeval(send_timeout))
        else:
            self.sock.settimeout(send_timeout)

    def _set_rcv(self, timeout: float) -> None:
        """Call when ``timeout`` is above ``_rcv`` or more than ``_TIMEOUT_SLACK`` below it."""
        if _KERNEL_TIMEOUTS:
            self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVTIMEO, _timeval(timeout))
        else:
            self.sock.settimeout(max(timeout, 1e-6))
        self._rcv = timeout


class SyncTransport:
    datagram = False
    peer = ""

    def send(self, data: bytes) -> None:
        raise NotImplementedError

    def send_frames(self, frames: list[bytes]) -> None:
        self.send(b"".join(frames))

    def recv(self, timeout: float) -> bytes:
        raise NotImplementedError

    def close(self) -> None:
        raise NotImplementedError


class TcpSyncTransport(SyncTransport, _SocketWaits):
    def __init__(self, ep: Endpoint, timeout: float) -> None:
        src = (ep.bind, 0) if ep.bind else None
        self.sock = socket.create_connection((ep.host, ep.port), timeout, source_address=src)
        self.sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self._init_waits(timeout)
        peer = self.sock.getpeername()
        self.peer = f"{peer[0]}:{peer[1]}"
        self.send = self.sock.sendall  # type: ignore[method-assign,assignment]  # one call less per request

    def send(self, data: bytes) -> None:
        self.sock.sendall(data)

    def recv(self, timeout: float) -> bytes:
        cur = self._rcv
        if timeout > cur or timeout < cur - _TIMEOUT_SLACK:
            self._set_rcv(timeout)
        try:
            data = self.sock.recv(_RECV_SIZE)
        except (BlockingIOError, TimeoutError):  # SO_RCVTIMEO expired (EAGAIN) / Python-level timeout
            return b""
        if not data:
            raise ConnectionResetError("the gripper closed the connection")
        return data

    def close(self) -> None:
        try:
            self.sock.shutdown(socket.SHUT_RDWR)
        except OSError:
            pass
        self.sock.close()


class UdpSyncTransport(SyncTransport, _SocketWaits):
    datagram = True

    def __init__(self, ep: Endpoint, timeout: float) -> None:
        infos = socket.getaddrinfo(ep.host, ep.port, type=socket.SOCK_DGRAM)
        family, _, _, _, remote = infos[0]
        self.remote: tuple[Any, ...] = tuple(remote)
        self.sock = socket.socket(family, socket.SOCK_DGRAM)
        bind = ep.bind or ("::" if family == socket.AF_INET6 else "0.0.0.0")
        self.sock.bind((bind, ep.reply_port))
        self.local_port: int = self.sock.getsockname()[1]
        self._init_waits(timeout)
        self.peer = f"{self.remote[0]}:{self.remote[1]}"

    def send(self, data: bytes) -> None:
        self.sock.sendto(data, self.remote)

    def send_frames(self, frames: list[bytes]) -> None:
        for f in frames:
            self.sock.sendto(f, self.remote)

    def recv(self, timeout: float) -> bytes:
        cur = self._rcv
        if timeout > cur or timeout < cur - _TIMEOUT_SLACK:
            self._set_rcv(timeout)
        while True:
            try:
                return self.sock.recv(_DGRAM_SIZE)
            except (BlockingIOError, TimeoutError):
                return b""
            except ConnectionRefusedError:
                continue  # ICMP port unreachable from an earlier send: keep waiting

    def close(self) -> None:
        self.sock.close()


class SerialSyncTransport(SyncTransport):
    """pyserial opens and configures the port; reads go through select() on its fd (pyserial's own
    timeout setter reconfigures the port on every change)."""

    def __init__(self, ep: Endpoint, timeout: float) -> None:
        import serial

        try:
            self.port = serial.serial_for_url(ep.path, baudrate=ep.baudrate, timeout=0, write_timeout=timeout)
        except (serial.SerialException, ValueError) as exc:
            raise ConnectionRefusedError(f"cannot open {ep.path}: {exc}") from exc
        self.fd: int = self.port.fileno()
        self.peer = ep.path

    def send(self, data: bytes) -> None:
        try:
            self.port.write(data)
        except Exception as exc:
            raise ConnectionResetError(f"serial write failed: {exc}") from exc

    def recv(self, timeout: float) -> bytes:
        r, _, _ = select.select([self.fd], [], [], max(timeout, 0.0))
        if not r:
            return b""
        try:
            data = os.read(self.fd, _RECV_SIZE)
        except BlockingIOError:
            return b""
        except OSError as exc:  # EIO: the pty's other end is gone
            raise ConnectionResetError(f"serial port: {exc}") from exc
        if not data:
            raise ConnectionResetError("serial port closed")
        return data

    def close(self) -> None:
        try:
            self.port.close()
        except Exception:
            pass
