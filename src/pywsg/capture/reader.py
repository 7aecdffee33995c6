"""WSG frames from packet captures (pcap / pcapng, read with dpkt), from JSON lines (``wsg proxy
--jsonl``, ``wsg --log-file``) and from hex-dump files.

TCP streams are reassembled per direction (sequence numbers; retransmissions and overlaps trimmed,
out-of-order segments held until the gap fills) and parsed with the protocol's incremental
:class:`~pywsg.protocol.FrameParser`, so a frame split over segments, or several frames in one
segment, decode as they would on the gripper. UDP carries one frame per datagram.

Direction: a segment to a gripper port (TCP 1000, UDP 1500 by default, or the side that received
the SYN) is a request, one from it a reply; otherwise the decoder guesses per frame.
"""

from __future__ import annotations

import heapq
import ipaddress
import math
import re
import struct
from collections.abc import Collection, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, BinaryIO, Literal

import dpkt

from ..protocol import Frame, FrameParser, FrameTooLarge, GarbageSkipped
from ..protocol.crc import crc16
from ..protocol.decode import DecodedFrame, Direction, decode_bytes, decode_frame, parse_hex
from ..protocol.frame import OVERHEAD
from .commlog import wall_clock

__all__ = [
    "DEFAULT_PORTS", "CapturedFrame", "LoggedFrame", "bytes_from_file", "frames_from_capture", "frames_from_jsonl",
    "is_capture", "is_jsonl", "read_hexdump",
]

# TCP command port, UDP listen / reply ports: the factory settings (000 §1.1 leaves them to the web interface)
DEFAULT_PORTS = frozenset({1000, 1500, 1501})
_PCAP_MAGICS = {b"\xd4\xc3\xb2\xa1", b"\xa1\xb2\xc3\xd4", b"\x4d\x3c\xb2\xa1", b"\xa1\xb2\x3c\x4d"}
_PCAPNG_MAGIC = b"\x0a\x0d\x0d\x0a"
_SEQ_MOD = 1 << 32
MAX_HELD = 1024 * 1024
"""Bytes of TCP segments held behind a gap before the gap is taken as lost (bytes missing from the capture)."""
Transport = Literal["tcp", "udp"]


@dataclass
class CapturedFrame:
    """One decoded frame (or stream problem) from a capture."""

    time: float  # capture timestamp, Unix seconds (of the packet that completed the frame)
    transport: Transport
    src: str  # "host:port"
    dst: str
    decoded: DecodedFrame

    def to_json(self) -> dict[str, Any]:
        return {"time": round(self.time, 6), "transport": self.transport, "src": self.src, "dst": self.dst,
                **self.decoded.to_json()}

    def header(self) -> str:
        return f"{wall_clock(self.time)} {self.transport.upper()} {self.src} -> {self.dst}"


def is_capture(path: str | Path) -> bool:
    """True when the file starts with a pcap or pcapng magic number."""
    with open(path, "rb") as f:
        magic = f.read(4)
    return magic in _PCAP_MAGICS or magic == _PCAPNG_MAGIC


@dataclass
class LoggedFrame:
    """One frame of a JSON-lines communication log (``wsg proxy --jsonl``, ``wsg --log-file``)."""

    time: float  # Unix seconds, as logged
    direction: str  # "tx" (client to gripper) or "rx"
    decoded: DecodedFrame

    def to_json(self) -> dict[str, Any]:
        return {"time": self.time, "log_direction": self.direction, **self.decoded.to_json()}

    def header(self) -> str:
        way = "client -> gripper" if self.direction == "tx" else "gripper -> client"
        return f"{wall_clock(self.time)} {self.direction.upper()} ({way})"


def is_jsonl(path: str | Path) -> bool:
    """True when the file's first non-blank character opens a JSON object (a JSON-lines log)."""
    with open(path, "rb") as f:
        head = f.read(256).lstrip()
    return head.startswith(b"{")


MAX_JSON_NESTING = 64
"""Opening brackets and braces a JSON-lines log line may hold (a frame line has one)."""


def jsonl_records(path: str | Path) -> Iterator[tuple[float, str, bytes]]:
    """(time s, ``"tx"``/``"rx"``, frame bytes) of each frame line of a JSON-lines log, in order: each
    line ``{"time": s, "direction": "tx"|"rx", "hex": "AA AA ..."}`` (other keys ignored; lines of
    other events skipped). Raises ValueError naming the line when one is not JSON or its hex is bad."""
    import json

    for n, line in enumerate(Path(path).read_text(encoding="utf-8").splitlines(), 1):
        if not line.strip():
            continue
        # A frame line nests one level. Python 3.11 raises RecursionError for ~1,000 levels, 3.13 parses
        # thousands, so a limit of our own gives every version the same answer (and bounded work).
        if line.count("[") + line.count("{") > MAX_JSON_NESTING:
            raise ValueError(f"line {n}: not a JSON object (a JSON-lines log has one per line; "
                             f"this one nests more than {MAX_JSON_NESTING} levels)")
        try:
            obj = json.loads(line)
        except (ValueError, RecursionError):  # RecursionError: nested ~1,000 deep (before Python 3.13)
            raise ValueError(f"line {n}: not a JSON object (a JSON-lines log has one per line)") from None
        if not isinstance(obj, dict) or obj.get("direction") not in ("tx", "rx") or not obj.get("hex"):
            continue
        if not isinstance(obj["hex"], str):
            raise ValueError(f"line {n}: hex: must be a string of hex bytes")
        try:
            raw = parse_hex(obj["hex"])
        except ValueError as exc:
            raise ValueError(f"line {n}: {exc}") from None
        yield _seconds(obj.get("time"), n), obj["direction"], raw


def _seconds(value: Any, n: int) -> float:
    """A log line's ``time``: a finite number of seconds (missing: 0)."""
    if value is None:
        return 0.0
    if isinstance(value, int | float) and not isinstance(value, bool):
        try:
            t = float(value)
        except OverflowError:
            t = math.inf
        if math.isfinite(t):
            return t
    raise ValueError(f"line {n}: time: must be a number of seconds")


def frames_from_jsonl(path: str | Path, direction: Direction | None = None) -> list[LoggedFrame]:
    """The frames of a JSON-lines log (:func:`jsonl_records`), decoded afresh: ``tx`` lines as
    requests, ``rx`` as replies, unless ``direction`` says otherwise."""
    out: list[LoggedFrame] = []
    for when, way, raw in jsonl_records(path):
        as_: Direction = direction or ("request" if way == "tx" else "reply")
        out.extend(LoggedFrame(when, way, d) for d in decode_bytes(raw, as_))
    return out


_XXD = re.compile(r"^\s*[0-9a-fA-F]{4,}:\s+((?:[0-9a-fA-F]{2,4}\s?)+)")  # xxd: "00000000: aaaa aa01  ...."
_HEXDUMP_C = re.compile(r"^\s*[0-9a-fA-F]{4,}\s+((?:[0-9a-fA-F]{2}\s+)+)\s*\|")  # hexdump -C / od-like


def read_hexdump(text: str) -> bytes:
    """Bytes from a hex dump: plain hex in any spacing (``AA AA``, ``AAh``, ``0xAA``, ``aaaa``),
    ``xxd`` or ``hexdump -C`` output. ``#`` starts a comment."""
    out = bytearray()
    dump_c = False
    for raw_line in text.splitlines():
        line = raw_line.split("#", 1)[0].rstrip()
        if not line.strip():
            continue
        m = _HEXDUMP_C.match(line) if "|" in line else None
        if m:
            out += bytes.fromhex(m.group(1))
            dump_c = True
            continue
        if dump_c and re.fullmatch(r"\s*[0-9a-fA-F]{7,8}", line):
            continue  # hexdump -C ends with the total length
        if line.strip() == "*":
            raise ValueError("hexdump elided repeated lines ('*'): dump with hexdump -v -C")
        m = _XXD.match(line)
        if m:
            out += bytes.fromhex(m.group(1).replace(" ", ""))
            continue
        out += parse_hex(line)
    return bytes(out)


def bytes_from_file(path: str | Path) -> bytes:
    """A file's bytes: read as a hex dump when it is text, else taken as raw binary frames."""
    data = Path(path).read_bytes()
    try:
        text = data.decode("ascii")
    except UnicodeDecodeError:
        return data
    if "\x00" in text or (data[:3] == b"\xaa\xaa\xaa"):
        return data
    return read_hexdump(text)


# --- link layers -------------------------------------------------------------------------------

def _ip_from_link(linktype: int, buf: bytes) -> Any:
    """The IPv4/IPv6 packet inside one captured link-layer frame, or None."""
    pkt: Any
    if linktype == dpkt.pcap.DLT_EN10MB:
        pkt = dpkt.ethernet.Ethernet(buf).data
    elif linktype in (dpkt.pcap.DLT_NULL, dpkt.pcap.DLT_LOOP):
        pkt = dpkt.loopback.Loopback(buf).data
    elif linktype == dpkt.pcap.DLT_LINUX_SLL:
        pkt = dpkt.sll.SLL(buf).data
    elif linktype == dpkt.pcap.DLT_LINUX_SLL2:
        pkt = dpkt.sll2.SLL2(buf).data
    elif linktype in (dpkt.pcap.DLT_RAW, 101, 14, dpkt.pcap.DLT_IPV4, dpkt.pcap.DLT_IPV6):
        if not buf:
            return None
        pkt = dpkt.ip.IP(buf) if buf[0] >> 4 == 4 else dpkt.ip6.IP6(buf)
    else:
        raise ValueError(f"unsupported link type {linktype} (read: Ethernet, loopback, Linux SLL, raw IP)")
    return pkt if isinstance(pkt, dpkt.ip.IP | dpkt.ip6.IP6) else None


def _addr(raw: bytes) -> str:
    return str(ipaddress.ip_address(raw))


def _endpoint(raw: bytes, port: int) -> str:
    host = _addr(raw)
    return f"[{host}]:{port}" if ":" in host else f"{host}:{port}"


def _packets(f: BinaryIO) -> tuple[int, Iterator[tuple[float, bytes]]]:
    magic = f.read(4)
    f.seek(0)
    if magic == _PCAPNG_MAGIC:
        reader: Any = dpkt.pcapng.Reader(f)
    elif magic in _PCAP_MAGICS:
        reader = dpkt.pcap.Reader(f)
    else:
        raise ValueError("not a pcap or pcapng file")
    return int(reader.datalink()), iter(reader)


# --- TCP reassembly and frame extraction -------------------------------------------------------

@dataclass
class _Stream:
    """One direction of one TCP connection (or one UDP flow's datagrams)."""

    src: str
    dst: str
    direction: Direction | None
    next_seq: int | None = None
    # out-of-order segments: a heap of (position relative to next_seq when held + bytes fed so far, n, ts, seq, data)
    held: list[tuple[int, int, float, int, bytes]] = field(default_factory=list)
    fed: int = 0  # bytes fed to the parser so far (an unwrapped stream position)
    held_bytes: int = 0
    parser: FrameParser = field(default_factory=lambda: FrameParser(verify_checksum=False))
    buf: bytearray = field(default_factory=bytearray)  # bytes fed to the parser, not yet attributed
    seen_frame: bool = False
    last_time: float = 0.0
    waiting: list[CapturedFrame] = field(default_factory=list)  # problems before the first frame


def _signed_delta(a: int, b: int) -> int:
    """a - b in 32-bit sequence space."""
    d = (a - b) % _SEQ_MOD
    return d - _SEQ_MOD if d >= _SEQ_MOD // 2 else d


class _Extractor:
    def __init__(self, ports: Collection[int]) -> None:
        self.ports = ports
        self.streams: dict[tuple[Transport, str, str], _Stream] = {}
        self.servers: set[str] = set()  # endpoints that received a SYN
        self._count = 0

    def stream(self, transport: Transport, src: str, sport: int, dst: str, dport: int) -> _Stream:
        key = (transport, src, dst)
        s = self.streams.get(key)
        if s is None:
            direction: Direction | None = None
            if dst in self.servers or (dport in self.ports and sport not in self.ports):
                direction = "request"
            elif src in self.servers or sport in self.ports:
                direction = "reply"
            s = self.streams[key] = _Stream(src, dst, direction)
            if transport == "udp" and dport == 1501:
                s.direction = "reply"
            if s.direction is None and transport == "udp":
                # ports say nothing: the side that spoke first is the client (a gripper only answers),
                # so a 41h request byte-identical to an IDLE reply is still a request
                back = self.streams.get((transport, dst, src))
                s.direction = "reply" if back is not None else "request"
                if back is not None and back.direction is None:
                    back.direction = "request"
        return s

    def tcp(self, ts: float, ip: Any, tcp: Any) -> Iterator[CapturedFrame]:
        src, dst = _endpoint(ip.src, tcp.sport), _endpoint(ip.dst, tcp.dport)
        syn = bool(tcp.flags & dpkt.tcp.TH_SYN)
        if syn and not tcp.flags & dpkt.tcp.TH_ACK:
            self.servers.add(dst)
        s = self.stream("tcp", src, tcp.sport, dst, tcp.dport)
        if syn:
            s.next_seq = (tcp.seq + 1) % _SEQ_MOD
            s.held.clear()
            s.held_bytes = 0
        data = bytes(tcp.data)
        if not data:
            return
        if s.next_seq is None:  # capture started mid-connection
            s.next_seq = tcp.seq
        pos = s.fed + _signed_delta(tcp.seq, s.next_seq)
        self._count += 1
        heapq.heappush(s.held, (pos, self._count, ts, tcp.seq, data))
        s.held_bytes += len(data)
        yield from self._drain(s, ts)
        if s.held_bytes > MAX_HELD:  # a gap that has not filled in 1 MiB: the segment is lost
            yield from self._skip_gap(s, "tcp")

    def _drain(self, s: _Stream, now: float) -> Iterator[CapturedFrame]:
        """Feed every held segment that is now in order (each is looked at once: a heap by stream
        position); frames are stamped ``now`` (their completion)."""
        while s.held and s.held[0][0] <= s.fed:
            pos, _n, _ts, _seq, data = heapq.heappop(s.held)
            s.held_bytes -= len(data)
            overlap = s.fed - pos
            if overlap >= len(data):
                continue  # pure retransmission
            fresh = data[overlap:]
            s.next_seq = ((s.next_seq or 0) + len(fresh)) % _SEQ_MOD
            s.fed += len(fresh)
            yield from self._feed(s, now, fresh, "tcp")

    def _skip_gap(self, s: _Stream, transport: Transport) -> Iterator[CapturedFrame]:
        """Give up on the missing bytes before the first held segment: report them, resync there."""
        pos, _n, ts, seq, _data = s.held[0]
        yield self._problem(s, ts, transport, f"{pos - s.fed} byte(s) missing from the capture")
        s.parser.clear()
        s.buf.clear()
        s.fed, s.next_seq = pos, seq
        yield from self._drain(s, ts)

    def finish(self) -> Iterator[CapturedFrame]:
        """End of capture: report gaps that never filled and partial frames."""
        for (transport, _src, _dst), s in self.streams.items():
            while s.held and s.next_seq is not None:  # data after a gap (lost segment): parse it after a resync
                yield from self._skip_gap(s, transport)
            rest = s.parser.pending()
            if rest and s.seen_frame:
                for d in decode_bytes(rest, s.direction):
                    yield CapturedFrame(s.last_time, transport, s.src, s.dst, d)

    def udp(self, ts: float, ip: Any, udp: Any) -> Iterator[CapturedFrame]:
        src, dst = _endpoint(ip.src, udp.sport), _endpoint(ip.dst, udp.dport)
        s = self.stream("udp", src, udp.sport, dst, udp.dport)
        data = bytes(udp.data)
        if not data:
            return
        decoded = decode_bytes(data, s.direction)
        if not any(d.error is None for d in decoded) and not s.seen_frame:
            return  # not WSG traffic
        s.seen_frame = True
        for d in decoded:
            yield CapturedFrame(ts, "udp", src, dst, d)

    def _problem(
        self, s: _Stream, ts: float, transport: Transport, msg: str, raw: bytes = b""
    ) -> CapturedFrame:
        decoded = DecodedFrame(raw, None, "-", "unknown", None, error=msg)
        return CapturedFrame(ts, transport, s.src, s.dst, decoded)

    def _feed(self, s: _Stream, ts: float, data: bytes, transport: Transport) -> Iterator[CapturedFrame]:
        s.last_time = ts
        s.buf += data
        off = 0
        for ev in s.parser.feed(data):
            if isinstance(ev, Frame):
                end = off + len(ev.payload) + OVERHEAD
                raw = bytes(s.buf[off:end])
                received = struct.unpack_from("<H", raw, len(raw) - 2)[0]
                d = decode_frame(ev, s.direction, (received, crc16(raw[:-2])))
                off = end
                if not s.seen_frame:
                    s.seen_frame = True
                    yield from s.waiting
                    s.waiting.clear()
                yield CapturedFrame(ts, transport, s.src, s.dst, d)
                continue
            if isinstance(ev, GarbageSkipped):
                problem = self._problem(s, ts, transport, ev.message, bytes(s.buf[off : off + ev.count]))
                off += ev.count
            elif isinstance(ev, FrameTooLarge):
                problem = self._problem(s, ts, transport, ev.message)
                off += 1
            else:  # pragma: no cover - no other events without checksum verification
                problem = self._problem(s, ts, transport, ev.message)
            if s.seen_frame:
                yield problem
            elif len(s.waiting) < 16:
                s.waiting.append(problem)
        del s.buf[:off]


def frames_from_capture(path: str | Path, ports: Collection[int] | None = None) -> list[CapturedFrame]:
    """Every WSG frame in a pcap/pcapng file, in capture order.

    ``ports``: gripper-side ports that decide the direction (default 1000, 1500, 1501); traffic on
    other ports is still searched for frames. Flows without a single frame are left out, so a
    capture of a whole network segment shows just the WSG conversation.
    Raises ValueError for files that are not captures or use an unsupported link type.
    """
    ex = _Extractor(frozenset(ports) if ports is not None else DEFAULT_PORTS)
    out: list[CapturedFrame] = []
    with open(path, "rb") as f:
        try:
            linktype, packets = _packets(f)
        except (dpkt.UnpackError, struct.error, EOFError, ValueError) as exc:
            raise ValueError(f"not a readable capture: {exc or type(exc).__name__}") from None
        n = 0
        ts = 0.0
        while True:
            try:
                ts, buf = next(packets)
            except StopIteration:
                break
            except (dpkt.UnpackError, struct.error, EOFError, ValueError, OverflowError, MemoryError) as exc:
                # a truncated file or a block with an impossible length: keep what was read, say where it ended
                what = str(exc) or type(exc).__name__
                msg = f"capture damaged after packet {n} ({what[:80]}): the rest is not read"
                out.extend(ex.finish())
                out.append(CapturedFrame(float(ts), "tcp", "-", "-",
                                         DecodedFrame(b"", None, "-", "unknown", None, error=msg)))
                return out
            n += 1
            try:
                ip = _ip_from_link(linktype, buf)
            except (dpkt.UnpackError, IndexError, struct.error):
                continue  # damaged link header: not ours to decode
            if ip is None:
                continue
            l4 = ip.data
            if isinstance(l4, dpkt.tcp.TCP):
                out.extend(ex.tcp(float(ts), ip, l4))
            elif isinstance(l4, dpkt.udp.UDP):
                out.extend(ex.udp(float(ts), ip, l4))
    out.extend(ex.finish())
    return out

