"""asyncio transports of the driver: TCP (``BufferedProtocol``), UDP (datagrams), serial (fd reader).

A transport moves bytes only: it hands what it reads to ``on_data(bytes-like)`` (stream
transports) or ``on_datagram(bytes)`` (UDP), and reports the end with ``on_lost(exc)``.

TCP uses ``BufferedProtocol`` with one preallocated 64 KiB receive buffer: asyncio's plain
``Protocol`` reads into a fresh 256 KiB buffer each time, which under glibc costs an mmap/munmap
per read and caps a client at ~11k round trips/s on this machine class (~18k with this design).
"""

from __future__ import annotations

import asyncio
import builtins
import os
import socket
from collections.abc import Callable
from typing import Any

from ..url import Endpoint

OnData = Callable[[memoryview], None]
OnDatagram = Callable[[bytes], None]
OnLost = Callable[[BaseException | None], None]

_RECV_SIZE = 65536

#: What ``asyncio.wait_for`` raises when its time is up. Python 3.10: ``asyncio.TimeoutError`` is its
#: own class, not the builtin ``TimeoutError`` (they are one class from 3.11 on), so catch both.
WAIT_TIMEOUT: tuple[type[Exception], ...] = (asyncio.TimeoutError, builtins.TimeoutError)


class AsyncTransport:
    """Base: ``write(data)``, ``write_frames(frames)``, ``close()``; ``datagram`` tells UDP apart."""

    datagram = False
    peer = ""

    def write(self, data: bytes) -> None:
        raise NotImplementedError

    def write_frames(self, frames: list[bytes]) -> None:
        self.write(b"".join(frames))

    def raw_socket(self) -> Any:
        """The OS socket (TCP, UDP), or None."""
        return None

    def close(self) -> None:
        raise NotImplementedError

    async def wait_closed(self, timeout: float) -> None:
        """After :meth:`close`: wait (at most ``timeout`` s) until the OS socket is really closed."""


class _TcpProtocol(asyncio.BufferedProtocol):
    def __init__(self, on_data: OnData, on_lost: OnLost) -> None:
        self._buf = memoryview(bytearray(_RECV_SIZE))
        self._on_data = on_data
        self._on_lost = on_lost
        self.closed: asyncio.Future[None] = asyncio.get_running_loop().create_future()

    def get_buffer(self, sizehint: int) -> memoryview:
        return self._buf

    def buffer_updated(self, nbytes: int) -> None:
        self._on_data(self._buf[:nbytes])

    def eof_received(self) -> bool:
        return False  # close our side too

    def connection_lost(self, exc: Exception | None) -> None:
        if not self.closed.done():
            self.closed.set_result(None)
        self._on_lost(exc)


class TcpTransport(AsyncTransport):
    def __init__(self, transport: asyncio.Transport, protocol: _TcpProtocol) -> None:
        self._t = transport
        self._p = protocol
        peer = transport.get_extra_info("peername")
        self.peer = f"{peer[0]}:{peer[1]}" if peer else ""

    @classmethod
    async def connect(cls, ep: Endpoint, on_data: OnData, on_lost: OnLost, timeout: float) -> TcpTransport:
        loop = asyncio.get_running_loop()
        local: tuple[str, int] | None = (ep.bind, 0) if ep.bind else None
        t, p = await asyncio.wait_for(
            loop.create_connection(lambda: _TcpProtocol(on_data, on_lost), ep.host, ep.port, local_addr=local),
            timeout,
        )
        sock = t.get_extra_info("socket")
        if sock is not None:  # asyncio sets TCP_NODELAY already; be explicit, the protocol is request/reply
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        return cls(t, p)

    def write(self, data: bytes) -> None:
        self._t.write(data)

    def raw_socket(self) -> Any:
        return self._t.get_extra_info("socket")

    def close(self) -> None:
        self._t.close()

    async def wait_closed(self, timeout: float) -> None:
        # asyncio closes the socket one loop turn after close() (call_soon(_call_connection_lost))
        try:
            await asyncio.wait_for(asyncio.shield(self._p.closed), timeout)
        except WAIT_TIMEOUT:
            pass

    def abort(self) -> None:
        self._t.abort()


class _UdpProtocol(asyncio.DatagramProtocol):
    def __init__(self, on_datagram: OnDatagram, on_lost: OnLost) -> None:
        self._on_datagram = on_datagram
        self._on_lost = on_lost

    def datagram_received(self, data: bytes, addr: Any) -> None:
        self._on_datagram(data)

    def error_received(self, exc: Exception) -> None:
        pass  # ICMP port unreachable etc.: the call's timeout reports it

    def connection_lost(self, exc: Exception | None) -> None:
        self._on_lost(exc)


class UdpTransport(AsyncTransport):
    """One socket bound to the reply port; requests go to host:port, one frame per datagram."""

    datagram = True

    def __init__(self, transport: asyncio.DatagramTransport, remote: tuple[Any, ...]) -> None:
        self._t = transport
        self._remote = remote
        self.peer = f"{remote[0]}:{remote[1]}"
        sock = transport.get_extra_info("sockname")
        self.local_port: int = sock[1] if sock else 0

    @classmethod
    async def connect(cls, ep: Endpoint, on_datagram: OnDatagram, on_lost: OnLost, timeout: float) -> UdpTransport:
        loop = asyncio.get_running_loop()
        infos = await loop.getaddrinfo(ep.host, ep.port, type=socket.SOCK_DGRAM)
        family, _, _, _, remote = infos[0]
        bind = ep.bind or ("::" if family == socket.AF_INET6 else "0.0.0.0")
        t, _ = await loop.create_datagram_endpoint(
            lambda: _UdpProtocol(on_datagram, on_lost), local_addr=(bind, ep.reply_port), family=family
        )
        return cls(t, remote)

    def write(self, data: bytes) -> None:
        self._t.sendto(data, self._remote)

    def write_frames(self, frames: list[bytes]) -> None:
        for f in frames:
            self._t.sendto(f, self._remote)

    def close(self) -> None:
        self._t.close()


class SerialTransport(AsyncTransport):
    """pyserial port read through the event loop's fd reader (no thread, no executor)."""

    def __init__(self, port: Any, on_data: OnData, on_lost: OnLost) -> None:
        self._port = port
        self._fd: int = port.fileno()
        self._on_data = on_data
        self._on_lost = on_lost
        self._loop = asyncio.get_running_loop()
        self._closed = False
        self.peer = port.port or ""
        self._loop.add_reader(self._fd, self._readable)

    @classmethod
    async def connect(cls, ep: Endpoint, on_data: OnData, on_lost: OnLost, timeout: float) -> SerialTransport:
        import serial  # pyserial

        try:
            port = serial.serial_for_url(ep.path, baudrate=ep.baudrate, timeout=0, write_timeout=timeout)
        except (serial.SerialException, OSError, ValueError) as exc:
            raise ConnectionRefusedError(f"cannot open {ep.path}: {exc}") from exc
        return cls(port, on_data, on_lost)

    def _readable(self) -> None:
        try:
            data = os.read(self._fd, _RECV_SIZE)
        except BlockingIOError:
            return
        except OSError as exc:  # EIO: the other end of a pty went away
            self._lost(exc)
            return
        if not data:
            self._lost(None)
            return
        self._on_data(memoryview(data))

    def _lost(self, exc: BaseException | None) -> None:
        if self._closed:
            return
        self._shutdown()
        self._on_lost(exc or ConnectionResetError("serial port closed"))

    def write(self, data: bytes) -> None:
        if self._closed:
            raise ConnectionResetError("serial port closed")
        try:
            self._port.write(data)
        except Exception as exc:
            self._lost(exc)
            raise ConnectionResetError(f"serial write failed: {exc}") from exc

    def close(self) -> None:
        if self._closed:
            return
        self._shutdown()
        self._loop.call_soon(self._on_lost, None)

    def _shutdown(self) -> None:
        self._closed = True
        self._loop.remove_reader(self._fd)
        try:
            self._port.close()
        except Exception:
            pass
