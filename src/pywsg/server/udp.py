"""UDP command interface (default: listen on 1500, answer to the client's address on port 1501).

One frame per datagram: a datagram gets at most one answer, to its first frame (or the first error
in it); what follows is ignored (:func:`~pywsg.protocol.parse_datagram`), so nothing is amplified.
The device answers to the sender's IP on the configured remote port
(``reply_port``, factory setting 1501 that public UDP drivers assume), or to the sender's own port
when ``reply_port`` is None. There is one device session for the UDP interface: auto-update packets
go to the last client that sent a datagram. Empty and oversized datagrams are handled by the device's
datagram parser (a header that announces more than the datagram holds is a truncated frame).

No reply loops. UDP has no connection, so two devices that answer each other (or one answering
itself) would exchange frames forever. A gripper therefore never answers

- a datagram from a UDP interface of this process (its own port, e.g. with ``reply_port=None`` and a
  forged source, or a sibling gripper of ``wsg sim --count N``),
- a datagram whose reply would go to such an interface (``reply_port`` = its own or a sibling's port),
- a frame that can only be a reply: a command with a fixed-size request, a payload of another
  size, starting with a known status code (another device's answer, not a malformed request).
Such datagrams are counted in :attr:`UdpServer.ignored` and logged once.
"""

from __future__ import annotations

import asyncio
import ipaddress
import logging
from collections.abc import Callable
from typing import Any, cast

from ..protocol import CATALOG, PREAMBLE, Frame, Status
from .device_api import GripperLike
from .limits import DEFAULT_LIMITS, Limits, droppable
from .netfault import Shaper, net_faults
from .scheduler import DeviceRunner
from .trace import log_replies

log = logging.getLogger("pywsg.server.udp")

Address = tuple[str, int]

_LOCAL_PORTS: dict[int, int] = {}
"""UDP ports served by this process (port -> number of servers on it)."""
_STATUS_CODES = frozenset(int(s) for s in Status)
_FIXED_REQUEST = {
    cid: spec.request_layout.fixed_size for cid, spec in CATALOG.items() if spec.request_layout.variable is None
}


def looks_like_reply(data: bytes) -> bool:
    """True if ``data`` is one frame that can only be a reply (see the module doc)."""
    if len(data) < 10 or data[:3] != PREAMBLE:
        return False
    size = data[4] | (data[5] << 8)
    fixed = _FIXED_REQUEST.get(data[3])
    return (fixed is not None and size != fixed and size >= 2 and len(data) == size + 8
            and (data[6] | (data[7] << 8)) in _STATUS_CODES)


def _is_local(ip: str) -> bool:
    try:
        return ipaddress.ip_address(ip).is_loopback
    except ValueError:
        return False


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
        self.ignored = 0
        """Datagrams not answered to prevent a reply loop (module doc)."""
        self._registered = False
        self.net = net_faults(gripper)
        """Network faults (drop, reorder, latency, silence; :mod:`pywsg.server.netfault`)."""
        self.shaper = Shaper(self.net, self._sendto, ordered=False)

    def _sendto(self, data: bytes) -> None:
        if self.transport is not None and self.client is not None:
            self.transport.sendto(data, self.client)

    def _writer(self, addr: Address) -> Callable[[bytes], None]:
        """A datagram delayed by the network faults goes to ``addr``, the client that asked, not to
        whoever sent last by the time it leaves."""

        def write(data: bytes) -> None:
            if self.transport is not None:
                self.transport.sendto(data, addr)

        return write

    async def start(self) -> UdpServer:
        loop = asyncio.get_running_loop()
        transport, _ = await loop.create_datagram_endpoint(
            lambda: self, local_addr=(self.host, self.requested_port)
        )
        self.port = transport.get_extra_info("sockname")[1]
        _LOCAL_PORTS[self.port] = _LOCAL_PORTS.get(self.port, 0) + 1
        self._registered = True
        return self

    def _ours(self, addr: Address) -> bool:
        """``addr`` is a UDP interface of this process (own or sibling gripper)."""
        return addr[1] in _LOCAL_PORTS and (addr[0] == self.host or _is_local(addr[0]))

    def _ignore(self, why: str, addr: Address) -> None:
        if self.ignored == 0:
            log.warning("udp %s:%s: %s: not answered (prevents a reply loop)", addr[0], addr[1], why)
        self.ignored += 1

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
        if addr != self._last_addr:  # a polling client sends from one address: check it once
            sender = (str(addr[0]), int(addr[1]))
            if self._ours(sender):
                self._ignore("datagram from a UDP interface of this process", sender)
                return
            client = (sender[0], sender[1] if self.reply_port is None else self.reply_port)
            if self._ours(client):
                self._ignore(f"reply port {client[1]} is a UDP interface of this process", sender)
                return
            self._last_addr = addr
            self.client = client
        if looks_like_reply(data):
            self._ignore("a reply frame", (str(addr[0]), int(addr[1])))
            return
        net = self.net
        if net.active:
            if net.swallow(data) or net.lose():
                return  # silent gripper, or the request datagram lost on the way
            data = net.garble_bytes(data)
        replies = self.gripper.handle_datagram(self.session, data)
        if replies and log.isEnabledFor(logging.INFO):
            log_replies(log, f"udp {addr[0]}:{addr[1]}", replies)
        t = self.transport
        if t is None:
            return
        if net.active or self.shaper.busy:
            if replies and self.client is not None:
                write = self._writer(self.client)
                for frame in replies:
                    self.shaper.send(frame.encode(), write)
            return
        for frame in replies:
            t.sendto(frame.encode(), self.client)

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
        if self.net.active or self.shaper.busy:
            self.shaper.send(frame.encode(), self._writer(self.client))
            return
        t.sendto(frame.encode(), self.client)

    async def close(self) -> None:
        if self._registered:
            self._registered = False
            _LOCAL_PORTS[self.port] -= 1
            if not _LOCAL_PORTS[self.port]:
                del _LOCAL_PORTS[self.port]
        if self.session is not None:
            self.gripper.close_session(self.session)
            self.session = None
        self.shaper.close()
        if self.transport is not None:
            self.transport.close()
            await asyncio.sleep(0)
