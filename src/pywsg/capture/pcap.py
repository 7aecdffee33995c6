"""Writing captures: :class:`PcapWriter` records a proxied exchange as a pcapng file (dpkt) that
Wireshark and ``wsg decode -f`` (:mod:`.reader`) read back. Used by ``wsg proxy --pcap``
(:mod:`pywsg.testing.proxy`)."""

from __future__ import annotations

import socket
import threading
import time
from pathlib import Path
from typing import Any, BinaryIO

import dpkt

__all__ = ["FLUSH_S", "MAX_SEGMENT", "PcapWriter"]

MAX_SEGMENT = 65535 - 20 - 20
"""TCP payload bytes per synthetic IPv4 packet (the IPv4 total length is 16 bits)."""
FLUSH_S = 0.2
"""The pcapng file is flushed at least this often while packets come (s) and on close."""


class PcapWriter:
    """Writes the proxied exchange as raw-IPv4 pcapng (link type 101) with TCP sequence numbers."""

    def __init__(self, path: str | Path) -> None:
        self._f: BinaryIO = open(path, "wb")  # noqa: SIM115 - closed in close()
        self._w = dpkt.pcapng.Writer(self._f, snaplen=65535, linktype=dpkt.pcap.DLT_RAW)
        self._seq: dict[tuple[str, int, str, int], int] = {}
        self._lock = threading.Lock()
        self._flushed = time.monotonic()

    @staticmethod
    def _ip(src: tuple[str, int], dst: tuple[str, int], l4: Any, proto: int) -> bytes:
        ip = dpkt.ip.IP(src=socket.inet_aton(src[0]), dst=socket.inet_aton(dst[0]), p=proto, ttl=64, data=l4)
        ip.len = len(ip)
        return bytes(ip)

    def _write(self, pkt: bytes, ts: float) -> None:
        with self._lock:
            self._w.writepkt(pkt, ts=ts)
            now = time.monotonic()
            if now - self._flushed >= FLUSH_S:  # streamed to disk, without a write call per packet
                self._f.flush()
                self._flushed = now

    def flush(self) -> None:
        with self._lock:
            if not self._f.closed:
                self._f.flush()
                self._flushed = time.monotonic()

    def tcp_open(self, client: tuple[str, int], server: tuple[str, int], ts: float) -> None:
        """A SYN from the client: ``wsg decode -f`` then knows which side is the gripper."""
        self._seq[client + server] = 1001
        self._seq[server + client] = 5001
        syn = dpkt.tcp.TCP(sport=client[1], dport=server[1], seq=1000, flags=dpkt.tcp.TH_SYN)
        self._write(self._ip(client, server, syn, dpkt.ip.IP_PROTO_TCP), ts)

    def tcp(self, src: tuple[str, int], dst: tuple[str, int], data: bytes, ts: float) -> None:
        """``data`` as TCP segments of at most :data:`MAX_SEGMENT` bytes (one read may be 256 KiB)."""
        key = src + dst
        for i in range(0, len(data), MAX_SEGMENT):
            part = data[i : i + MAX_SEGMENT]
            seq = self._seq.get(key, 1)
            self._seq[key] = (seq + len(part)) % (1 << 32)
            seg = dpkt.tcp.TCP(sport=src[1], dport=dst[1], seq=seq, flags=dpkt.tcp.TH_ACK | dpkt.tcp.TH_PUSH,
                               data=part)
            self._write(self._ip(src, dst, seg, dpkt.ip.IP_PROTO_TCP), ts)

    def tcp_fin(self, src: tuple[str, int], dst: tuple[str, int], ts: float) -> None:
        """A FIN: that side shut down its writing (half-close)."""
        seq = self._seq.get(src + dst, 1)
        fin = dpkt.tcp.TCP(sport=src[1], dport=dst[1], seq=seq, flags=dpkt.tcp.TH_ACK | dpkt.tcp.TH_FIN)
        self._write(self._ip(src, dst, fin, dpkt.ip.IP_PROTO_TCP), ts)

    def udp(self, src: tuple[str, int], dst: tuple[str, int], data: bytes, ts: float) -> None:
        dg = dpkt.udp.UDP(sport=src[1], dport=dst[1], data=data[: 65535 - 28])
        dg.ulen = len(dg)
        self._write(self._ip(src, dst, dg, dpkt.ip.IP_PROTO_UDP), ts)

    def close(self) -> None:
        with self._lock:
            if not self._f.closed:
                self._f.close()
