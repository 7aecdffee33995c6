"""TCP command interface (default port 1000).

Each connection gets a device session (its auto-update subscriptions, its 07h disconnect
announcement). The device lets one TCP session at a time hold the command interface; a further
connection is accepted and every frame it sends is answered E_ACCESS_DENIED (docs/fidelity.md, "A
refused TCP client"; as after 07h, 000 §3.1.2), so nobody
steals motion control silently; it stays refused even after the controlling client leaves (the *next*
connection gets control). Closing the controlling connection without 07h raises FAST STOP unless that
setting is off (device rule). Refused connections that stay silent are closed after a while.

Every write holds whole frames (public clients read field by field), TCP_NODELAY is on, and output
is bounded (see :class:`~pywsg.server.limits.Limits`).
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import socket
import struct
import time
from typing import Any, cast

from ..protocol import Frame
from .device_api import GripperLike
from .limits import DEFAULT_LIMITS, Limits, droppable
from .netfault import NetFaults, Shaper, net_faults
from .scheduler import DeviceRunner, Scheduler
from .trace import log_replies

log = logging.getLogger("pywsg.server.tcp")

READ_SLICE = 4 * 1024
"""Bytes of one client parsed per event-loop turn (~0.5-3 ms of work even for hostile input)."""


def tune_socket(sock: socket.socket | None, limits: Limits) -> None:
    """TCP_NODELAY, keepalive against half-open connections, optional small send buffer."""
    if sock is None:
        return
    try:
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_KEEPALIVE, 1)
        if hasattr(socket, "TCP_KEEPIDLE"):
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_KEEPIDLE, limits.keepalive_idle)
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_KEEPINTVL, 1)
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_KEEPCNT, 3)
        if limits.socket_sndbuf:
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, limits.socket_sndbuf)
    except OSError:  # not every platform has every option
        pass


class TcpConnection(asyncio.Protocol):
    """One TCP client: the controller (device session) or a refused second client."""

    def __init__(self, server: TcpServer) -> None:
        self.server = server
        self.transport: asyncio.Transport | None = None
        self.session: Any = None
        self.peer = "?"
        self.refused = False
        """Another client holds the command interface: the device answers E_ACCESS_DENIED."""
        self._out: list[Frame] = []
        self._sched = server.runner.scheduler
        self._soft = server.limits.output_soft
        self.dropped = 0
        """Auto-update packets dropped because the client did not read."""
        self.last_rx = time.monotonic()
        self._paused = False
        self._backlog = b""
        """Read bytes not parsed yet: a big read is parsed one slice per loop turn (see data_received)."""
        self.net: NetFaults = server.net
        self.shaper = Shaper(self.net, self._write)
        """Network faults (latency, bandwidth, slicer, silence; :mod:`pywsg.server.netfault`) on the replies."""
        self._net_timer: asyncio.TimerHandle | None = None

    # -- asyncio.Protocol ------------------------------------------------------------------
    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        transport = cast(asyncio.Transport, transport)  # uvloop's is no asyncio.Transport subclass
        self.transport = transport
        srv = self.server
        peer = transport.get_extra_info("peername")
        self.peer = f"{peer[0]}:{peer[1]}" if isinstance(peer, tuple) else str(peer)
        if len(srv.connections) >= srv.limits.max_connections:
            log.warning("tcp %s: too many connections, closed", self.peer)
            transport.abort()
            return
        srv.connections.add(self)
        tune_socket(transport.get_extra_info("socket"), srv.limits)
        transport.set_write_buffer_limits(high=srv.limits.high_water)
        self.session = srv.gripper.open_session("tcp", peer=self.peer, deliver=self.deliver)
        self.refused = bool(getattr(self.session, "denied", False))
        if self.refused:
            log.info("tcp %s: connected while another client holds control: E_ACCESS_DENIED", self.peer)
        else:
            srv.controller = self
            log.info("tcp %s: connected (controls the gripper)", self.peer)
        if self.net.active:
            srv.net_rules(self)

    def data_received(self, data: bytes) -> None:
        if self.net.active:
            if self.net.swallow(data):
                return  # a silent gripper: the request is never executed
            data = self.net.garble_bytes(data)
        if self.refused:  # only refused clients are reaped when silent
            self.last_rx = time.monotonic()
        if self._backlog:
            self._backlog += data  # reading pauses while a backlog is worked off; a read may still land
            return
        if len(data) <= READ_SLICE:
            self._handle(data)
            return
        # One read can hold 256 KiB. Parse it a slice per loop turn so every other client of the
        # process (other grippers, UDP, Modbus, web) is served in between, and read nothing more
        # from this client until it is done.
        self._backlog = data
        if self.transport is not None:
            self.transport.pause_reading()
        self._work_backlog()

    def _work_backlog(self) -> None:
        t = self.transport
        if t is None or t.is_closing() or self.session is None:
            self._backlog = b""
            return
        chunk, self._backlog = self._backlog[:READ_SLICE], self._backlog[READ_SLICE:]
        self._handle(chunk)
        if self._backlog:
            asyncio.get_running_loop().call_soon(self._work_backlog)
        elif not self._paused and not t.is_closing():
            t.resume_reading()

    def _handle(self, data: bytes) -> None:
        replies = self.server.gripper.feed(self.session, data)
        if replies:
            if log.isEnabledFor(logging.INFO):
                log_replies(log, f"tcp {self.peer}", replies)
            t = self.transport
            if t is None or t.is_closing():
                return
            self.shaper.send(replies[0].encode() if len(replies) == 1 else b"".join([f.encode() for f in replies]))
            if t.get_write_buffer_size() > self.server.limits.output_hard:
                self._close_unread(t)

    def _write(self, data: bytes) -> None:
        t = self.transport
        if t is not None and not t.is_closing():
            t.write(data)

    def reset(self) -> None:
        """Reset the connection (RST, "connection reset by peer" at the client)."""
        t = self.transport
        if t is None or t.is_closing():
            return
        sock = t.get_extra_info("socket")
        if sock is not None:
            with contextlib.suppress(OSError):  # linger 0: close() sends RST instead of FIN
                sock.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
        self.net.counts["reset"] += 1
        log.info("tcp %s: reset (network fault)", self.peer)
        t.abort()

    def close_later(self, delay: float, reset: bool) -> None:
        """Reset (or close) this connection ``delay`` s from now (network faults reset, silent)."""
        if self._net_timer is not None:
            self._net_timer.cancel()
        loop = asyncio.get_running_loop()
        fn = self.reset if reset else self._close_quietly
        self._net_timer = loop.call_later(delay, fn) if delay > 0 else None
        if delay <= 0:
            fn()

    def _close_quietly(self) -> None:
        if self.transport is not None and not self.transport.is_closing():
            log.info("tcp %s: closed by the gripper", self.peer)
            self.transport.close()

    def connection_lost(self, exc: Exception | None) -> None:
        srv = self.server
        srv.connections.discard(self)
        self._out.clear()
        self.shaper.close()
        if self._net_timer is not None:
            self._net_timer.cancel()
        if srv.controller is self:
            srv.controller = None
        session, self.session = self.session, None
        if session is not None:
            srv.gripper.close_session(session)  # the device decides on FAST STOP
            log.info("tcp %s: disconnected%s", self.peer, f" ({exc})" if exc else "")
        self.transport = None

    def pause_writing(self) -> None:
        # a client that does not read its replies: stop reading its requests until it does
        if self.transport is not None and not self._paused:
            self._paused = True
            self.transport.pause_reading()

    def resume_writing(self) -> None:
        if self.transport is not None and self._paused:
            self._paused = False
            if not self._backlog:
                self.transport.resume_reading()

    # -- output ------------------------------------------------------------------------------
    @property
    def buffered(self) -> int:
        """Bytes waiting to go out to this client (ours and the transport's)."""
        t = self.transport
        return sum(len(f.payload) + 8 for f in self._out) + (t.get_write_buffer_size() if t is not None else 0)

    def deliver(self, frame: Frame) -> None:
        """Deferred frame from the device (final reply, auto-update). Called during poll().

        Kept as a frame until the scheduler round ends (one write per connection and round); the
        soft-limit drop is decided then, on what the transport still holds.
        """
        out = self._out
        out.append(frame)
        if len(out) == 1:
            sched = self._sched or self.server.runner.scheduler
            if sched is not None and sched.in_round:
                sched.mark_dirty(self)
            else:
                self.flush()

    def flush(self) -> None:
        out = self._out
        if not out:
            return
        self._out = []
        t = self.transport
        if t is None or t.is_closing():
            return
        if t.get_write_buffer_size() > self._soft:
            kept = [f for f in out if not droppable(f.command_id)]  # final replies are never lost
            self.dropped += len(out) - len(kept)
            if not kept:
                return
            out = kept
        self.shaper.send(out[0].encode() if len(out) == 1 else b"".join([f.encode() for f in out]))
        if t.get_write_buffer_size() > self.server.limits.output_hard:
            self._close_unread(t)

    def _close_unread(self, t: asyncio.Transport) -> None:
        log.warning("tcp %s: %d bytes unread, connection closed", self.peer, t.get_write_buffer_size())
        t.abort()


class TcpServer:
    """Serves ``gripper`` on ``host:port`` (port 0: any free port; read :attr:`port`)."""

    def __init__(
        self,
        gripper: GripperLike,
        runner: DeviceRunner,
        host: str = "127.0.0.1",
        port: int = 1000,
        limits: Limits = DEFAULT_LIMITS,
    ) -> None:
        self.gripper = gripper
        self.runner = runner
        self.host = host
        self.requested_port = port
        self.limits = limits
        self.connections: set[TcpConnection] = set()
        self.controller: TcpConnection | None = None
        self._server: asyncio.Server | None = None
        self._reaper: asyncio.Task[None] | None = None
        self.port = 0
        self.net = net_faults(gripper)
        """This gripper's network faults (shared with its UDP and serial interfaces)."""

    @property
    def scheduler(self) -> Scheduler | None:
        return self.runner.scheduler

    async def start(self) -> TcpServer:
        loop = asyncio.get_running_loop()
        self._server = await loop.create_server(
            lambda: TcpConnection(self), self.host, self.requested_port, reuse_address=True, backlog=128
        )
        self.port = self._server.sockets[0].getsockname()[1]
        self._reaper = loop.create_task(self._reap_idle_refused())
        self.net.listeners.append(self._on_net)
        return self

    def _on_net(self, what: str) -> None:
        """A network fault was switched on (``reset``, ``silent``) or the gripper interrupts (``interrupt``)."""
        for conn in list(self.connections):
            if what == "interrupt":
                conn.close_later(0, reset=False)
            else:
                self.net_rules(conn)

    def net_rules(self, conn: TcpConnection) -> None:
        """Apply reset / silent-with-close to ``conn`` (just connected, or a fault just switched on)."""
        s = self.net.s
        if s.reset is not None:
            conn.close_later(s.reset, reset=True)
        elif s.silent and s.close_after:
            conn.close_later(s.close_after, reset=False)

    async def _reap_idle_refused(self) -> None:
        # refused second clients that stay silent are closed; the controller is kept (keepalive covers it)
        period = max(self.limits.denied_idle / 4, 0.05)
        while True:
            await asyncio.sleep(period)
            cutoff = time.monotonic() - self.limits.denied_idle
            for conn in list(self.connections):
                if conn.refused and conn.last_rx < cutoff and conn.transport is not None:
                    conn.transport.close()

    @property
    def address(self) -> str:
        return f"tcp://{self.host}:{self.port}"

    async def close(self) -> None:
        with contextlib.suppress(ValueError):
            self.net.listeners.remove(self._on_net)
        if self._reaper is not None:
            self._reaper.cancel()
            try:
                await self._reaper
            except asyncio.CancelledError:
                pass
            self._reaper = None
        if self._server is not None:
            self._server.close()
            for conn in list(self.connections):
                if conn.transport is not None:
                    conn.transport.abort()
            await self._server.wait_closed()
            self._server = None
        await asyncio.sleep(0)  # let connection_lost run
