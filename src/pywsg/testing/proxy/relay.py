"""The relaying side of ``wsg proxy``: the :class:`Proxy`, its TCP pipes and its UDP sockets.

Bytes are forwarded the moment they arrive; the pcapng gets them next and the decoders
(:mod:`.decode`) last. Network faults (:mod:`pywsg.server.netfault`) act after the tap.
"""

from __future__ import annotations

import asyncio
import collections
import contextlib
import socket
import struct
import time
from pathlib import Path
from typing import Any, Literal, cast

from ...capture.commlog import CommLog
from ...capture.pcap import PcapWriter
from ...client.url import parse_url
from ...server.netfault import NetFaults, Shaper
from .capture import LogGate, ProxyStats
from .decode import Decoder

__all__ = ["CLOSE_GRACE_S", "HIGH_WATER", "UDP_UPSTREAMS", "Proxy"]

Transport = Literal["tcp", "udp"]

HIGH_WATER = 64 * 1024
"""Bytes buffered toward one side at which reading from the other side pauses."""
CLOSE_GRACE_S = 2.0
"""How long the gripper side stays open for replies in flight after its client has gone (s)."""
UDP_UPSTREAMS = 256
"""Upstream UDP sockets (one per client address) at most; the least recently used one goes first."""


class _Upstream(asyncio.Protocol):
    """Proxy -> gripper connection: gripper bytes go straight to the client."""

    def __init__(self, pipe: _Pipe) -> None:
        self.pipe = pipe

    def data_received(self, data: bytes) -> None:
        self.pipe.from_gripper(data)

    def eof_received(self) -> bool:
        self.pipe.gripper_eof()
        return True

    def pause_writing(self) -> None:  # the gripper is slow to read: stop reading the client
        self.pipe.hold_client("upstream full", True)

    def resume_writing(self) -> None:
        self.pipe.hold_client("upstream full", False)

    def connection_lost(self, exc: Exception | None) -> None:
        self.pipe.upstream_lost()


class _Pipe(asyncio.Protocol):
    """Client -> proxy connection and its upstream twin."""

    def __init__(self, proxy: Proxy) -> None:
        self.proxy = proxy
        self.client: asyncio.Transport | None = None
        self.upstream: asyncio.Transport | None = None
        self.tx = Decoder(proxy, "tx", lambda on: self.hold_client("decoding", on))
        self.rx = Decoder(proxy, "rx", lambda on: self.hold_upstream("decoding", on))
        self.peer: tuple[str, int] = ("0.0.0.0", 0)
        self.closed = False
        self.client_gone = False
        self.client_eof = False
        self.gripper_eofd = False
        self._client_holds: set[str] = {"connecting"}
        self._upstream_holds: set[str] = set()
        self.shaper = Shaper(proxy.net, self._to_client, hold=lambda on: self.hold_upstream("net fault", on))
        """Network faults on the gripper's bytes toward the client (after the tap: the capture has them as sent)."""
        self._net_timer: asyncio.TimerHandle | None = None
        self._early: list[bytes] = []  # client bytes read before the gripper side was up (Python 3.10)

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        assert isinstance(transport, asyncio.Transport)
        self.client = transport
        self.peer = transport.get_extra_info("peername")[:2]
        sock = transport.get_extra_info("socket")
        if sock is not None:
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        transport.set_write_buffer_limits(high=HIGH_WATER)
        self.proxy.stats.connections += 1
        self.proxy._pipes.add(self)
        if self.proxy.net.active:
            self.net_rules()
            if self.closed:  # reset at once (timeout 0)
                return
        transport.pause_reading()  # until the gripper side is up
        # Python 3.10's selector transport adds its reader *after* connection_made (a callback queued
        # before it), ignoring a pause made here (3.11 checks is_reading() first), and a second
        # pause_reading() is then a no-op. So on 3.10 the client can be read before the gripper side is
        # up: data_received keeps it in _early, and this resume/pause pair, queued behind the transport's
        # own callback, stops reading for real until _connect is done.
        asyncio.get_running_loop().call_soon(self._repause)
        task = asyncio.get_running_loop().create_task(self._connect())
        self.proxy._tasks.add(task)
        task.add_done_callback(self.proxy._tasks.discard)

    async def _connect(self) -> None:
        loop = asyncio.get_running_loop()
        try:
            transport, _ = await loop.create_connection(lambda: _Upstream(self), self.proxy.host, self.proxy.port)
        except OSError as exc:
            if self.proxy.log is not None:
                self.proxy.log.note("tx", f"cannot reach {self.proxy.host}:{self.proxy.port}: {exc.strerror or exc}")
            self.close()
            return
        self.upstream = transport
        if self.closed:
            transport.close()
            return
        sock = transport.get_extra_info("socket")
        if sock is not None:
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        transport.set_write_buffer_limits(high=HIGH_WATER)
        if self.proxy.pcap is not None:
            self.proxy.pcap.tcp_open(self.peer, self.proxy.server_addr, time.time())
        for reason in list(self._upstream_holds):  # holds taken before it existed
            self._upstream_holds.discard(reason)
            self.hold_upstream(reason, True)
        early, self._early = self._early, []
        for data in early:
            self._forward(data)
        self.hold_client("connecting", False)

    def _repause(self) -> None:
        c = self.client
        if self.upstream is None and c is not None and not c.is_closing() and self._client_holds:
            c.resume_reading()
            c.pause_reading()

    # -- flow control: a set of reasons per side; reading resumes when none is left
    def hold_client(self, reason: str, on: bool) -> None:
        was = bool(self._client_holds)
        (self._client_holds.add if on else self._client_holds.discard)(reason)
        if self.client is not None and not self.client_gone and was != bool(self._client_holds):
            (self.client.pause_reading if on else self.client.resume_reading)()

    def hold_upstream(self, reason: str, on: bool) -> None:
        was = bool(self._upstream_holds)
        (self._upstream_holds.add if on else self._upstream_holds.discard)(reason)
        if self.upstream is not None and was != bool(self._upstream_holds):
            (self.upstream.pause_reading if on else self.upstream.resume_reading)()

    def pause_writing(self) -> None:  # the client is slow to read: stop reading the gripper
        self.hold_upstream("client full", True)

    def resume_writing(self) -> None:
        self.hold_upstream("client full", False)

    # -- data
    def data_received(self, data: bytes) -> None:
        if self.upstream is None:  # read before the gripper side was up: only on Python 3.10 (_repause)
            self._early.append(data)
            return
        self._forward(data)

    def _forward(self, data: bytes) -> None:
        assert self.upstream is not None
        net = self.proxy.net
        if not net.active:
            self.upstream.write(data)  # forward first: the tap adds no waiting
        elif not net.swallow(data):  # a silent gripper never gets the request
            self.upstream.write(net.garble_bytes(data))
        if self.proxy.pcap is not None:
            self.proxy.pcap.tcp(self.peer, self.proxy.server_addr, data, time.time())
        self.tx.feed(data)

    def from_gripper(self, data: bytes) -> None:
        if self.client is not None and not self.client_gone:
            self.shaper.send(data)
        if self.proxy.pcap is not None:
            self.proxy.pcap.tcp(self.proxy.server_addr, self.peer, data, time.time())
        self.rx.feed(data)

    # -- ends: half-close passes through; a client gone leaves the gripper side open for replies in flight
    def eof_received(self) -> bool:
        self.client_eof = True
        if self.proxy.pcap is not None:
            self.proxy.pcap.tcp_fin(self.peer, self.proxy.server_addr, time.time())
        if self.upstream is not None and self.upstream.can_write_eof():
            self.upstream.write_eof()
        if self.gripper_eofd:
            self.close()
        return True

    def gripper_eof(self) -> None:
        self.gripper_eofd = True
        if self.proxy.pcap is not None:
            self.proxy.pcap.tcp_fin(self.proxy.server_addr, self.peer, time.time())
        if self.client is not None and not self.client_gone and self.client.can_write_eof():
            self.client.write_eof()
        if self.client_eof or self.client_gone:
            self.close()

    def connection_lost(self, exc: Exception | None) -> None:
        self.client_gone = True
        if self.closed or self.upstream is None or self.upstream.is_closing():
            self.close()
            return
        if not self.client_eof and self.upstream.can_write_eof():
            self.client_eof = True
            self.upstream.write_eof()
        self._upstream_holds.clear()
        self.upstream.resume_reading()
        asyncio.get_running_loop().call_later(CLOSE_GRACE_S, self.close)

    def _to_client(self, data: bytes) -> None:
        if self.client is not None and not self.client_gone and not self.client.is_closing():
            self.client.write(data)

    def net_rules(self) -> None:
        """Network faults reset / silent-with-timeout for this connection (new, or a fault just switched on)."""
        s = self.proxy.net.s
        if s.reset is not None:
            self._close_later(s.reset, reset=True)
        elif s.silent and s.close_after:
            self._close_later(s.close_after, reset=False)

    def _close_later(self, delay: float, reset: bool) -> None:
        if self._net_timer is not None:
            self._net_timer.cancel()
        fn = self.reset if reset else self.close
        if delay > 0:
            self._net_timer = asyncio.get_running_loop().call_later(delay, fn)
        else:
            self._net_timer = None
            fn()

    def reset(self) -> None:
        """Reset the client's connection (RST) as a gripper's network stack would; the gripper side closes."""
        c = self.client
        if c is not None and not c.is_closing():
            sock = c.get_extra_info("socket")
            if sock is not None:
                with contextlib.suppress(OSError):
                    sock.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
            self.proxy.net.counts["reset"] += 1
            c.abort()
        self.close()

    def upstream_lost(self) -> None:
        self.gripper_eofd = True
        self.close()

    def close(self) -> None:
        if self.closed:
            return
        self.closed = True
        self.proxy._pipes.discard(self)
        self.shaper.close()
        if self._net_timer is not None:
            self._net_timer.cancel()
        for t in (self.client, self.upstream):
            if t is not None:
                t.close()


class _UdpUpstream(asyncio.DatagramProtocol):
    """Proxy -> gripper datagrams for one client address (or, on a fixed reply port, for all)."""

    def __init__(self, proxy: Proxy, client: tuple[str, int] | None) -> None:
        self.proxy = proxy
        self.client = client
        self.rx = Decoder(proxy, "rx")
        self.transport: asyncio.DatagramTransport | None = None
        self.last = time.monotonic()

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        self.transport = cast(asyncio.DatagramTransport, transport)

    def datagram_received(self, data: bytes, addr: tuple[str | Any, int]) -> None:
        self.last = time.monotonic()
        lp = self.proxy._udp_proto
        client = self.client or (lp.route(data) if lp is not None else None)
        listener = self.proxy._udp_listener
        if listener is not None and client is not None:
            self.proxy.udp_shaper(client).send(data)
        if self.proxy.pcap is not None and client is not None:
            self.proxy.pcap.udp(self.proxy.server_addr, client, data, time.time())
        self.rx.feed(data, datagram=True)


class _UdpListener(asyncio.DatagramProtocol):
    def __init__(self, proxy: Proxy) -> None:
        self.proxy = proxy
        self.ups: collections.OrderedDict[tuple[str, int], _UdpUpstream] = collections.OrderedDict()
        self.shared: _UdpUpstream | None = None  # fixed reply port: one socket for every client
        self.opening: set[tuple[str, int]] = set()
        self.tx = Decoder(proxy, "tx")
        self.pending: dict[tuple[str, int], list[bytes]] = {}
        # fixed reply port: (client, command ID) of requests not yet answered, oldest first
        self.waiting: collections.deque[tuple[tuple[str, int], int]] = collections.deque(maxlen=1024)
        self.last_client: tuple[str, int] | None = None

    def route(self, reply: bytes) -> tuple[str, int] | None:
        """The client a reply on the shared socket belongs to."""
        if len(reply) > 3:
            for i, (client, cid) in enumerate(self.waiting):
                if cid == reply[3]:
                    del self.waiting[i]
                    return client
        return self.last_client

    def datagram_received(self, data: bytes, addr: tuple[str | Any, int]) -> None:
        client = (str(addr[0]), int(addr[1]))
        self.last_client = client
        if self.proxy.pcap is not None:
            self.proxy.pcap.udp(client, self.proxy.server_addr, data, time.time())
        self.tx.feed(data, datagram=True)
        net = self.proxy.net
        if net.active:
            if net.swallow(data) or net.lose():
                return  # a silent gripper, or the datagram lost on the way (after the tap)
            data = net.garble_bytes(data)
        if self.proxy.reply_port:
            if len(data) > 3:
                self.waiting.append((client, data[3]))
            up = self.shared
            key: tuple[str, int] = ("", 0)
        else:
            up = self.ups.get(client)
            key = client
            if up is not None:
                self.ups.move_to_end(client)
        if up is not None and up.transport is not None:
            up.last = time.monotonic()
            up.transport.sendto(data)
            return
        queue = self.pending.setdefault(key, [])
        if len(queue) < 64:  # datagrams held while the socket opens; more are dropped, as UDP may
            queue.append(data)
        if key not in self.opening:
            self.opening.add(key)
            task = asyncio.get_running_loop().create_task(self._open(key))
            self.proxy._tasks.add(task)
            task.add_done_callback(self.proxy._tasks.discard)

    async def _open(self, key: tuple[str, int]) -> None:
        loop = asyncio.get_running_loop()
        shared = bool(self.proxy.reply_port)
        up = _UdpUpstream(self.proxy, None if shared else key)
        local = ("0.0.0.0", self.proxy.reply_port) if shared else None
        try:
            await loop.create_datagram_endpoint(lambda: up, local_addr=local,
                                                remote_addr=(self.proxy.host, self.proxy.port))
        except OSError as exc:
            self.pending.pop(key, None)
            if self.proxy.log is not None:
                self.proxy.log.note("tx", f"cannot open UDP to {self.proxy.host}:{self.proxy.port}: {exc}")
            return
        finally:
            self.opening.discard(key)
        self.proxy.stats.connections += 1
        if shared:
            self.shared = up
        else:
            while len(self.ups) >= UDP_UPSTREAMS:  # the least recently used socket makes room
                _, old = self.ups.popitem(last=False)
                if old.transport is not None:
                    old.transport.close()
            self.ups[key] = up
        assert up.transport is not None
        for data in self.pending.pop(key, []):
            up.transport.sendto(data)
        up.last = time.monotonic()  # opening may have taken a while: idle counts from now

    def reap(self, idle: float) -> None:
        """Close the per-client sockets without traffic for ``idle`` s."""
        now = time.monotonic()
        for key, up in list(self.ups.items()):
            if now - up.last >= idle:
                del self.ups[key]
                if up.transport is not None:
                    up.transport.close()

    def close(self) -> None:
        for up in [*self.ups.values(), *([self.shared] if self.shared else [])]:
            if up.transport is not None:
                up.transport.close()
        self.ups.clear()
        self.shared = None


class Proxy:
    """Listen on ``listen_host:listen_port`` and forward to ``target`` (``tcp://`` or ``udp://`` URL).

    ``log``: where decoded frames go (None: nowhere); ``pcap``: a pcapng file to write; ``log_rate``:
    comm-log entries a second at most (0: all); ``udp_idle``: seconds without traffic after which a
    client's upstream UDP socket is closed. Run it with ``await proxy.start()`` … ``await
    proxy.close()`` on a loop; ``port_bound`` is the bound port.
    """

    def __init__(self, target: str, listen_port: int = 0, listen_host: str = "127.0.0.1",
                 log: CommLog | None = None, pcap: str | Path | None = None, log_rate: int = 1000,
                 udp_idle: float = 60.0, net: NetFaults | None = None) -> None:
        ep = parse_url(target)
        if ep.scheme not in ("tcp", "udp"):
            raise ValueError(f"proxy target must be tcp:// or udp://, not {ep.scheme}://")
        self.transport: Transport = "tcp" if ep.scheme == "tcp" else "udp"
        self.host, self.port = ep.host, ep.port
        self.reply_port = ep.reply_port if self.transport == "udp" else 0
        self.listen_host, self.listen_port = listen_host, listen_port
        self.log = log
        self.stats = ProxyStats()
        self.gate = LogGate(log, log_rate, self.stats, captured=pcap is not None)
        self.udp_idle = udp_idle
        self.server_addr = (socket.gethostbyname(self.host), self.port)
        self.pcap = PcapWriter(pcap) if pcap is not None else None
        self._server: asyncio.AbstractServer | None = None
        self._pipes: set[_Pipe] = set()
        self._tasks: set[asyncio.Task[Any]] = set()
        self._udp_listener: asyncio.DatagramTransport | None = None
        self._udp_proto: _UdpListener | None = None
        self._ticker: asyncio.Task[None] | None = None
        self.port_bound = 0
        self.net = net or NetFaults()
        """Network faults between the gripper and the clients (:mod:`pywsg.server.netfault`): switch them with
        ``proxy.net.set(kind, params)`` on the proxy's loop, or over ``wsg proxy --control``."""
        self._udp_shapers: collections.OrderedDict[tuple[str, int], Shaper] = collections.OrderedDict()
        self.net.listeners.append(self._on_net)

    def _on_net(self, what: str) -> None:
        for pipe in list(self._pipes):
            if what == "interrupt":
                pipe.close()
            else:
                pipe.net_rules()

    def udp_shaper(self, client: tuple[str, int]) -> Shaper:
        """The shaper of the datagrams toward ``client`` (bounded like the upstream sockets)."""
        sh = self._udp_shapers.get(client)
        if sh is None:
            listener = self._udp_listener

            def send(data: bytes, client: tuple[str, int] = client) -> None:
                if listener is not None and not listener.is_closing():
                    listener.sendto(data, client)

            sh = self._udp_shapers[client] = Shaper(self.net, send, ordered=False)
            while len(self._udp_shapers) > UDP_UPSTREAMS:
                self._udp_shapers.popitem(last=False)[1].close()
        else:
            self._udp_shapers.move_to_end(client)
        return sh

    async def start(self) -> Proxy:
        loop = asyncio.get_running_loop()
        if self.transport == "tcp":
            self._server = await loop.create_server(lambda: _Pipe(self), self.listen_host, self.listen_port)
            self.port_bound = int(self._server.sockets[0].getsockname()[1])
        else:
            self._udp_proto = _UdpListener(self)
            transport, _ = await loop.create_datagram_endpoint(
                lambda: self._udp_proto or _UdpListener(self), local_addr=(self.listen_host, self.listen_port))
            self._udp_listener = transport
            self.port_bound = int(transport.get_extra_info("sockname")[1])
        self._ticker = loop.create_task(self._tick())
        return self

    async def _tick(self) -> None:
        """Once a second: flush the capture, write the log's 'not logged' line, reap idle UDP sockets."""
        while True:
            await asyncio.sleep(min(1.0, self.udp_idle / 4) if self.udp_idle > 0 else 1.0)
            if self.pcap is not None:
                self.pcap.flush()
            self.gate.roll()
            if self._udp_proto is not None and self.udp_idle > 0:
                self._udp_proto.reap(self.udp_idle)

    @property
    def address(self) -> str:
        return f"{self.transport}://{self.listen_host}:{self.port_bound}"

    async def close(self) -> None:
        with contextlib.suppress(ValueError):
            self.net.listeners.remove(self._on_net)
        for sh in self._udp_shapers.values():
            sh.close()
        if self._ticker is not None:
            self._ticker.cancel()
        for pipe in list(self._pipes):
            pipe.close()
        if self._server is not None:
            self._server.close()
            with contextlib.suppress(Exception):
                await asyncio.wait_for(self._server.wait_closed(), 2)
        if self._udp_listener is not None:
            self._udp_listener.close()
        if self._udp_proto is not None:
            self._udp_proto.close()
        with contextlib.suppress(Exception):  # what was read is decoded (bounded: the backlogs are)
            await asyncio.wait_for(asyncio.gather(*list(self._tasks), return_exceptions=True), 10)
        self.gate.summary()
        if self.pcap is not None:
            self.pcap.close()
