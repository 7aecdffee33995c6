"""Blocking transports of :class:`~pywsg.client.sync.Gripper`: plain sockets and a serial fd.

``recv(timeout)`` returns the bytes read, ``b""`` when ``timeout`` s passed without data, and
raises ``ConnectionError`` when the other side is gone.
"""

from __future__ import annotations

import os
import select
import socket
from typing import Any

from .url import Endpoint

_RECV_SIZE = 65536


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


class TcpSyncTransport(SyncTransport):
    def __init__(self, ep: Endpoint, timeout: float) -> None:
        src = (ep.bind, 0) if ep.bind else None
        self.sock = socket.create_connection((ep.host, ep.port), timeout, source_address=src)
        self.sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self._timeout: float | None = None
        peer = self.sock.getpeername()
        self.peer = f"{peer[0]}:{peer[1]}"

    def send(self, data: bytes) -> None:
        self.sock.sendall(data)

    def recv(self, timeout: float) -> bytes:
        if timeout != self._timeout:
            self.sock.settimeout(timeout)
            self._timeout = timeout
        try:
            data = self.sock.recv(_RECV_SIZE)
        except TimeoutError:
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


class UdpSyncTransport(SyncTransport):
    datagram = True

    def __init__(self, ep: Endpoint, timeout: float) -> None:
        infos = socket.getaddrinfo(ep.host, ep.port, type=socket.SOCK_DGRAM)
        family, _, _, _, remote = infos[0]
        self.remote: tuple[Any, ...] = tuple(remote)
        self.sock = socket.socket(family, socket.SOCK_DGRAM)
        bind = ep.bind or ("::" if family == socket.AF_INET6 else "0.0.0.0")
        self.sock.bind((bind, ep.reply_port))
        self.local_port: int = self.sock.getsockname()[1]
        self._timeout: float | None = None
        self.peer = f"{self.remote[0]}:{self.remote[1]}"

    def send(self, data: bytes) -> None:
        self.sock.sendto(data, self.remote)

    def send_frames(self, frames: list[bytes]) -> None:
        for f in frames:
            self.sock.sendto(f, self.remote)

    def recv(self, timeout: float) -> bytes:
        if timeout != self._timeout:
            self.sock.settimeout(timeout)
            self._timeout = timeout
        while True:
            try:
                return self.sock.recv(_RECV_SIZE)
            except TimeoutError:
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


def open_sync(ep: Endpoint, timeout: float) -> SyncTransport:
    if ep.scheme == "tcp":
        return TcpSyncTransport(ep, timeout)
    if ep.scheme == "udp":
        return UdpSyncTransport(ep, timeout)
    return SerialSyncTransport(ep, timeout)
