"""UDP command interface (default: listen on 1500, answer to the client's address on port 1501).

One frame per datagram. The device answers to the sender's IP on the configured remote port
(``reply_port``, factory setting 1501 that public UDP drivers assume), or to the sender's own port
when ``reply_port`` is None. There is one device session for the UDP interface: auto-update packets
go to the last client that sent a datagram. Empty and oversized datagrams are handled by the device's
datagram parser (a header that announces more than the datagram holds is a truncated frame).
"""

from __future__ import annotations

import asyncio
import logging
from typing import Any, cast

from ..protocol import Frame
from .device_api import GripperLike
from .limits import DEFAULT_LIMITS, Limits, droppable
from .scheduler import DeviceRunner
from .trace import log_replies

log = logging.getLogger("pywsg.server.udp")

Address = tuple[str, int]


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

    async def start(self) -> UdpServer:
        loop = asyncio.get_running_loop()
        transport, _ = await loop.create_datagram_endpoint(
            lambda: self, local_addr=(self.host, self.requested_port)
        )
        self.port = transport.get_extra_info("sockname")[1]
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
            self._last_addr = addr
            port = int(addr[1])
            self.client = (str(addr[0]), port if self.reply_port is None else self.reply_port)
        replies = self.gripper.handle_datagram(self.session, data)
        if replies and log.isEnabledFor(logging.INFO):
            log_replies(log, f"udp {addr[0]}:{addr[1]}", replies)
        t = self.transport
        if t is None:
            return
        client = self.client
        for frame in replies:
            t.sendto(frame.encode(), client)

    def error_received(self, exc: Exception) -> None:
        # ICMP port unreachable from a client that went away: nothing to do
        log.debug("udp: %s", exc)

    def connection_lost(self, exc: Exception | None) -> None:
        self.transport = None

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
