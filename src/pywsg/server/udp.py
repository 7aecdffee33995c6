"""UDP command interface (default: listen on 1500, answer to the client's address on port 1501).

One frame per datagram: only a datagram's first frame is read and answered (bytes after it are
ignored), so a datagram gets at most one reply. The device answers to the sender's IP on the configured remote port
(``reply_port``, factory setting 1501 that public UDP drivers assume), or to the sender's own port
when ``reply_port`` is None. There is one device session for the UDP interface: auto-update packets
go to the last client that sent a datagram. Empty and oversized datagrams are handled by the device's
datagram parser (a header that announces more than the datagram holds is a truncated frame).

No reply loops: a gripper ignores datagrams sent from any UDP command port of this process (its own
or a sibling's, e.g. ``--count 2`` where gripper 1 listens on gripper 0's reply port 1501) and never
sends a reply to one of them; such datagrams are counted in :attr:`UdpServer.looped`.
"""

from __future__ import annotations

import asyncio
import ipaddress
import logging
from typing import Any, cast

from ..protocol import Frame
from .device_api import GripperLike
from .limits import DEFAULT_LIMITS, Limits, droppable
from .scheduler import DeviceRunner
from .trace import log_replies

log = logging.getLogger("pywsg.server.udp")

Address = tuple[str, int]


_LOCAL_PORTS: dict[int, set[str]] = {}
"""UDP command ports bound in this process -> the hosts they are bound on."""


def _local_ip(ip: str, bound: set[str]) -> bool:
    if ip in bound or "0.0.0.0" in bound or "::" in bound:
        return True
    try:
        return ipaddress.ip_address(ip.split("%")[0]).is_loopback
    except ValueError:
        return False


def is_own_port(addr: tuple[str | Any, int]) -> bool:
    """True if ``addr`` is a UDP command port of this process (a datagram to or from it would loop)."""
    bound = _LOCAL_PORTS.get(int(addr[1]))
    return bound is not None and _local_ip(str(addr[0]), bound)


def _buffered(t: asyncio.DatagramTransport) -> int:
    size = getattr(t, "get_write_buffer_size", None)  # selector and uvloop transports have it
    return int(size()) if size is not None else 0


class UdpServer(asyncio.DatagramProtocol):
    """Serves ``gripper`` on UDP ``host:port`` (port 0: any free port; read :attr:`port`)."""

    def __init__(
        self,
        gripper: GripperLike,
        runner: DeviceRunner,
        host: str = "127.0.0.1",
        port: int = 1500,
        reply_port: int | None = 1501,
        limits: Limits = DEFAULT_LIMITS,
    ) -> None:
        self.gripper = gripper
        self.runner = runner
        self.host = host
        self.requested_port = port
        self.reply_port = reply_port
        self.limits = limits
        self.transport: asyncio.DatagramTransport | None = None
        self.session: Any = None
        self.client: Address | None = None
        """Where replies and auto-updates go (the last sender, on ``reply_port``)."""
        self._last_addr: Any = None
        self.port = 0
        self.dropped = 0
        self.datagrams = 0
        self.looped = 0
        """Datagrams ignored (or replies not sent) because they came from or went to one of our own ports."""

    async def start(self) -> UdpServer:
        loop = asyncio.get_running_loop()
        transport, _ = await loop.create_datagram_endpoint(
            lambda: self, local_addr=(self.host, self.requested_port)
        )
        self.port = transport.get_extra_info("sockname")[1]
        _LOCAL_PORTS.setdefault(self.port, set()).add(self.host)
        return self

    @property
    def address(self) -> str:
        if self.reply_port is None:
            return f"udp://{self.host}:{self.port}"
        return f"udp://{self.host}:{self.port}?reply_port={self.reply_port}"

    # -- asyncio.DatagramProtocol ------------------------------------------------------------
    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        self.transport = cast(asyncio.DatagramTransport, transport)
        self.session = self.gripper.open_session("udp", peer="udp", deliver=self.deliver)

    def datagram_received(self, data: bytes, addr: tuple[str | Any, int]) -> None:
        self.datagrams += 1
        if addr != self._last_addr:  # a polling client sends from one address: convert it once
            if is_own_port(addr):  # our own reply (self-loop) or a sibling gripper's
                self._looped(addr)
                return
            port = int(addr[1])
            client = (str(addr[0]), port if self.reply_port is None else self.reply_port)
            if is_own_port(client):  # the reply would land on a command port of ours
                self._looped(client)
                return
            self._last_addr = addr
            self.client = client
        replies = self.gripper.handle_datagram(self.session, data)
        if replies and log.isEnabledFor(logging.INFO):
            log_replies(log, f"udp {addr[0]}:{addr[1]}", replies)
        t = self.transport
        if t is None:
            return
        client = self.client
        for frame in replies:
            t.sendto(frame.encode(), client)

    def _looped(self, addr: tuple[str | Any, int]) -> None:
        if not self.looped:
            log.warning("udp %s: %s:%s is a UDP command port of this simulator: not answered (reply loop)",
                        self.port, addr[0], addr[1])
        self.looped += 1

    def error_received(self, exc: Exception) -> None:
        # ICMP port unreachable from a client that went away: nothing to do
        log.debug("udp: %s", exc)

    def connection_lost(self, exc: Exception | None) -> None:
        self.transport = None
        hosts = _LOCAL_PORTS.get(self.port)
        if hosts is not None:
            hosts.discard(self.host)
            if not hosts:
                del _LOCAL_PORTS[self.port]

    def deliver(self, frame: Frame) -> None:
        t = self.transport
        if t is None or self.client is None:
            return
        if droppable(frame.command_id) and _buffered(t) > self.limits.output_soft:
            self.dropped += 1
            return
        t.sendto(frame.encode(), self.client)

    async def close(self) -> None:
        if self.session is not None:
            self.gripper.close_session(self.session)
            self.session = None
        if self.transport is not None:
            self.transport.close()
            await asyncio.sleep(0)
