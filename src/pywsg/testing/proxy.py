"""A transparent tap between any WSG client and any WSG (real or virtual): ``wsg proxy``.

Bytes are forwarded unchanged and in order the moment they arrive (forwarding comes first, decoding
after), so the client and the gripper cannot tell the tap is there. Each complete frame is handed to
a :class:`~pywsg.cli.commlog.CommLog` (one decoded line per frame: time, TX/RX, command, status,
fields) and can be written to a pcapng file (readable by ``wsg decode -f``, ``wsg replay`` and
Wireshark) as synthetic IPv4 packets between the client's and the gripper's real addresses.

TCP: every client connection gets its own connection to the gripper (the gripper sees one client
per proxied client, as the command manual's single-client rule expects). UDP: datagrams from each
client address go out from a socket of their own; the gripper's replies go back to that client
address. For a gripper that replies to a fixed port (factory setting 1501) give ``?reply_port=1501``
in the target URL: the upstream socket is bound to that local port.
"""

from __future__ import annotations

import asyncio
import contextlib
import socket
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, BinaryIO, Literal, cast

import dpkt

from ..cli.commlog import CommLog, TxRx
from ..client.url import parse_url
from ..protocol import ChecksumMismatch, Frame, FrameParser, GarbageSkipped
from ..protocol.parser import parse_datagram

__all__ = ["PcapWriter", "Proxy", "ProxyStats"]

Transport = Literal["tcp", "udp"]


class PcapWriter:
    """Writes the proxied exchange as raw-IPv4 pcapng (link type 101) with TCP sequence numbers."""

    def __init__(self, path: str | Path) -> None:
        self._f: BinaryIO = open(path, "wb")  # noqa: SIM115 - closed in close()
        self._w = dpkt.pcapng.Writer(self._f, snaplen=65535, linktype=dpkt.pcap.DLT_RAW)
        self._seq: dict[tuple[str, int, str, int], int] = {}
        self._lock = threading.Lock()

    @staticmethod
    def _ip(src: tuple[str, int], dst: tuple[str, int], l4: Any, proto: int) -> bytes:
        ip = dpkt.ip.IP(src=socket.inet_aton(src[0]), dst=socket.inet_aton(dst[0]), p=proto, ttl=64, data=l4)
        ip.len = len(ip)
        return bytes(ip)

    def _write(self, pkt: bytes, ts: float) -> None:
        with self._lock:
            self._w.writepkt(pkt, ts=ts)
            self._f.flush()

    def tcp_open(self, client: tuple[str, int], server: tuple[str, int], ts: float) -> None:
        """A SYN from the client: ``wsg decode -f`` then knows which side is the gripper."""
        self._seq[client + server] = 1001
        self._seq[server + client] = 5001
        syn = dpkt.tcp.TCP(sport=client[1], dport=server[1], seq=1000, flags=dpkt.tcp.TH_SYN)
        self._write(self._ip(client, server, syn, dpkt.ip.IP_PROTO_TCP), ts)

    def tcp(self, src: tuple[str, int], dst: tuple[str, int], data: bytes, ts: float) -> None:
        key = src + dst
        seq = self._seq.get(key, 1)
        self._seq[key] = (seq + len(data)) % (1 << 32)
        seg = dpkt.tcp.TCP(sport=src[1], dport=dst[1], seq=seq, flags=dpkt.tcp.TH_ACK | dpkt.tcp.TH_PUSH,
                           data=data)
        self._write(self._ip(src, dst, seg, dpkt.ip.IP_PROTO_TCP), ts)

    def udp(self, src: tuple[str, int], dst: tuple[str, int], data: bytes, ts: float) -> None:
        dg = dpkt.udp.UDP(sport=src[1], dport=dst[1], data=data)
        dg.ulen = len(dg)
        self._write(self._ip(src, dst, dg, dpkt.ip.IP_PROTO_UDP), ts)

    def close(self) -> None:
        with self._lock:
            self._f.close()


@dataclass
class ProxyStats:
    """Counters of one proxy run."""

    connections: int = 0
    frames: dict[str, int] = field(default_factory=lambda: {"tx": 0, "rx": 0})
    bytes: dict[str, int] = field(default_factory=lambda: {"tx": 0, "rx": 0})


class _Decoder:
    """Frames out of one direction of one connection, into the comm log."""

    def __init__(self, log: CommLog | None, direction: TxRx, stats: ProxyStats) -> None:
        self.parser = FrameParser(verify_checksum=True)
        self.log = log
        self.direction = direction
        self.stats = stats

    def feed(self, data: bytes, datagram: bool = False) -> None:
        self.stats.bytes[self.direction] += len(data)
        events = parse_datagram(data) if datagram else self.parser.feed(data)
        for ev in events:
            if isinstance(ev, Frame):
                self.stats.frames[self.direction] += 1
                if self.log is not None:
                    self.log.record(self.direction, ev)
            elif self.log is not None:
                if isinstance(ev, ChecksumMismatch):
                    msg = f"{ev.command_id:02X}h checksum wrong: {ev.received:04X}h, expected {ev.expected:04X}h"
                elif isinstance(ev, GarbageSkipped):
                    msg = f"{ev.count} byte(s) outside any frame"
                else:
                    msg = type(ev).__name__
                self.log.note(self.direction, msg)


class _Upstream(asyncio.Protocol):
    """Proxy -> gripper connection: gripper bytes go straight to the client."""

    def __init__(self, pipe: _Pipe) -> None:
        self.pipe = pipe

    def data_received(self, data: bytes) -> None:
        self.pipe.from_gripper(data)

    def connection_lost(self, exc: Exception | None) -> None:
        self.pipe.close()


class _Pipe(asyncio.Protocol):
    """Client -> proxy connection and its upstream twin."""

    def __init__(self, proxy: Proxy) -> None:
        self.proxy = proxy
        self.client: asyncio.Transport | None = None
        self.upstream: asyncio.Transport | None = None
        self.early: list[bytes] = []
        self.tx = _Decoder(proxy.log, "tx", proxy.stats)
        self.rx = _Decoder(proxy.log, "rx", proxy.stats)
        self.peer: tuple[str, int] = ("0.0.0.0", 0)
        self.closed = False

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        assert isinstance(transport, asyncio.Transport)
        self.client = transport
        self.peer = transport.get_extra_info("peername")[:2]
        sock = transport.get_extra_info("socket")
        if sock is not None:
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self.proxy.stats.connections += 1
        self.proxy._pipes.add(self)
        transport.pause_reading()  # until the gripper side is up
        asyncio.get_running_loop().create_task(self._connect())

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
        sock = transport.get_extra_info("socket")
        if sock is not None:
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        if self.proxy.pcap is not None:
            self.proxy.pcap.tcp_open(self.peer, self.proxy.server_addr, time.time())
        if self.client is not None and not self.closed:
            self.client.resume_reading()

    def data_received(self, data: bytes) -> None:
        assert self.upstream is not None
        self.upstream.write(data)  # forward first: the tap adds no waiting
        if self.proxy.pcap is not None:
            self.proxy.pcap.tcp(self.peer, self.proxy.server_addr, data, time.time())
        self.tx.feed(data)

    def from_gripper(self, data: bytes) -> None:
        if self.client is not None:
            self.client.write(data)
        if self.proxy.pcap is not None:
            self.proxy.pcap.tcp(self.proxy.server_addr, self.peer, data, time.time())
        self.rx.feed(data)

    def connection_lost(self, exc: Exception | None) -> None:
        self.close()

    def close(self) -> None:
        if self.closed:
            return
        self.closed = True
        self.proxy._pipes.discard(self)
        for t in (self.client, self.upstream):
            if t is not None:
                t.close()


class _UdpUpstream(asyncio.DatagramProtocol):
    def __init__(self, proxy: Proxy, client: tuple[str, int]) -> None:
        self.proxy = proxy
        self.client = client
        self.rx = _Decoder(proxy.log, "rx", proxy.stats)
        self.transport: asyncio.DatagramTransport | None = None

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        self.transport = cast(asyncio.DatagramTransport, transport)

    def datagram_received(self, data: bytes, addr: tuple[str | Any, int]) -> None:
        listener = self.proxy._udp_listener
        if listener is not None:
            listener.sendto(data, self.client)
        if self.proxy.pcap is not None:
            self.proxy.pcap.udp(self.proxy.server_addr, self.client, data, time.time())
        self.rx.feed(data, datagram=True)


class _UdpListener(asyncio.DatagramProtocol):
    def __init__(self, proxy: Proxy) -> None:
        self.proxy = proxy
        self.ups: dict[tuple[str, int], _UdpUpstream] = {}
        self.tx = _Decoder(proxy.log, "tx", proxy.stats)
        self.pending: dict[tuple[str, int], list[bytes]] = {}

    def datagram_received(self, data: bytes, addr: tuple[str | Any, int]) -> None:
        client = (str(addr[0]), int(addr[1]))
        up = self.ups.get(client)
        if up is not None and up.transport is not None:
            up.transport.sendto(data)
        else:
            self.pending.setdefault(client, []).append(data)
            if up is None:
                asyncio.get_running_loop().create_task(self._open(client))
        if self.proxy.pcap is not None:
            self.proxy.pcap.udp(client, self.proxy.server_addr, data, time.time())
        self.tx.feed(data, datagram=True)

    async def _open(self, client: tuple[str, int]) -> None:
        loop = asyncio.get_running_loop()
        up = _UdpUpstream(self.proxy, client)
        self.ups[client] = up
        local = ("0.0.0.0", self.proxy.reply_port) if self.proxy.reply_port else None
        try:
            await loop.create_datagram_endpoint(lambda: up, local_addr=local,
                                                remote_addr=(self.proxy.host, self.proxy.port))
        except OSError as exc:
            del self.ups[client]
            if self.proxy.log is not None:
                self.proxy.log.note("tx", f"cannot open UDP to {self.proxy.host}:{self.proxy.port}: {exc}")
            return
        self.proxy.stats.connections += 1
        assert up.transport is not None
        for data in self.pending.pop(client, []):
            up.transport.sendto(data)


class Proxy:
    """Listen on ``listen_host:listen_port`` and forward to ``target`` (``tcp://`` or ``udp://`` URL).

    ``log``: where decoded frames go (None: nowhere); ``pcap``: a pcapng file to write. Run it with
    ``await proxy.start()`` … ``await proxy.close()`` on a loop; ``port`` is the bound port.
    """

    def __init__(self, target: str, listen_port: int = 0, listen_host: str = "127.0.0.1",
                 log: CommLog | None = None, pcap: str | Path | None = None) -> None:
        ep = parse_url(target)
        if ep.scheme not in ("tcp", "udp"):
            raise ValueError(f"proxy target must be tcp:// or udp://, not {ep.scheme}://")
        self.transport: Transport = "tcp" if ep.scheme == "tcp" else "udp"
        self.host, self.port = ep.host, ep.port
        self.reply_port = ep.reply_port if self.transport == "udp" else 0
        self.listen_host, self.listen_port = listen_host, listen_port
        self.log = log
        self.stats = ProxyStats()
        self.pcap = PcapWriter(pcap) if pcap is not None else None
        self.server_addr = (socket.gethostbyname(self.host), self.port)
        self._server: asyncio.AbstractServer | None = None
        self._pipes: set[_Pipe] = set()
        self._udp_listener: asyncio.DatagramTransport | None = None
        self._udp_proto: _UdpListener | None = None
        self.port_bound = 0

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
        return self

    @property
    def address(self) -> str:
        return f"{self.transport}://{self.listen_host}:{self.port_bound}"

    async def close(self) -> None:
        for pipe in list(self._pipes):
            pipe.close()
        if self._server is not None:
            self._server.close()
            with contextlib.suppress(Exception):
                await asyncio.wait_for(self._server.wait_closed(), 2)
        if self._udp_listener is not None:
            self._udp_listener.close()
        if self._udp_proto is not None:
            for up in self._udp_proto.ups.values():
                if up.transport is not None:
                    up.transport.close()
        if self.pcap is not None:
            self.pcap.close()


