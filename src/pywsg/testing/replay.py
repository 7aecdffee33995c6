"""Replay the client side of a recorded exchange against any gripper and compare the replies.

The recording is a pcap/pcapng file (``wsg proxy --pcap``, Wireshark, tcpdump) or JSON lines
(``wsg proxy --jsonl``, ``wsg --log-file``). Each recorded request is sent as its exact bytes, in
order; then the replies with its command ID are collected (as many as were recorded: an immediate
E_CMD_PENDING and the final reply of a motion count as two) before the next request goes out.

Compared exactly: the command ID, the status code and the payload layout (length, field names,
flags and enumerations). Compared within ``tolerance``: measured values (floating-point fields, in
their own units: mm, mm/s, N, °C). Timing is not compared.
"""

from __future__ import annotations

import collections
import math
import socket
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..client.url import parse_url
from ..protocol import Command, Frame, FrameParser
from ..protocol.decode import DecodedFrame, decode_bytes, decode_frame

__all__ = ["Difference", "ReplayReport", "Step", "load_steps", "replay"]

IDLE_WAIT = 0.02
"""Seconds of real time without a reply before ``replay(idle=...)`` calls ``idle`` (manual clocks)."""


@dataclass
class Step:
    """One recorded request and the replies recorded for it (frames with its command ID)."""

    request: bytes
    command_id: int
    command: str
    replies: list[bytes] = field(default_factory=list)


@dataclass
class Difference:
    step: int  # 1-based
    command: str
    what: str
    recorded: Any
    replayed: Any

    def line(self) -> str:
        return f"step {self.step} {self.command}: {self.what}: recorded {self.recorded}, got {self.replayed}"


@dataclass
class ReplayReport:
    steps: int = 0
    replies: int = 0
    differences: list[Difference] = field(default_factory=list)

    @property
    def matched(self) -> bool:
        return not self.differences

    def to_json(self) -> dict[str, Any]:
        return {"matched": self.matched, "steps": self.steps, "replies": self.replies,
                "differences": [d.__dict__ for d in self.differences]}


def _records(path: Path) -> Iterable[tuple[str, bytes]]:
    """(``tx``/``rx``, frame bytes) in recorded order."""
    from ..capture.reader import frames_from_capture, is_capture, jsonl_records

    if is_capture(path):
        for c in frames_from_capture(path):
            d = c.decoded
            if d.error and d.error.startswith("capture damaged"):
                raise ValueError(f"{path}: {d.error}")
            if d.command_id is None or d.error:
                continue
            yield ("tx" if d.direction == "request" else "rx"), d.raw
        return
    try:
        for _, direction, raw in jsonl_records(path):
            yield direction, raw
    except ValueError as exc:
        raise ValueError(f"{path}: {exc}: not a JSON lines log (give a pcap/pcapng file or JSON lines)") from None


def load_steps(path: str | Path) -> list[Step]:
    """The recorded requests with their replies, from a capture or a JSON-lines log."""
    steps: list[Step] = []
    latest: dict[int, Step] = {}  # the latest request with each ID owns its replies
    for direction, raw in _records(Path(path)):
        d = decode_bytes(raw, "request" if direction == "tx" else "reply")[0]
        if d.command_id is None:
            continue
        if direction == "tx":
            st = latest[d.command_id] = Step(raw, d.command_id, d.command)
            steps.append(st)
        elif (owner := latest.get(d.command_id)) is not None:
            owner.replies.append(raw)
    return steps


class _Link:
    def __init__(self, url: str, timeout: float, idle: Callable[[], None] | None = None) -> None:
        self.idle = idle
        ep = parse_url(url)
        if ep.scheme not in ("tcp", "udp"):
            raise ValueError(f"replay needs tcp:// or udp://, not {ep.scheme}://")
        self.udp = ep.scheme == "udp"
        self.timeout = timeout
        if self.udp:
            self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            self.sock.bind(("0.0.0.0" if ep.reply_port else "127.0.0.1", ep.reply_port or 0))
            self.addr = (ep.host, ep.port)
        else:
            self.sock = socket.create_connection((ep.host, ep.port), timeout=timeout)
            self.sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self.parser = FrameParser()
        self.frames: collections.deque[Frame] = collections.deque()

    def send(self, data: bytes) -> None:
        if self.udp:
            self.sock.sendto(data, self.addr)
        else:
            self.sock.sendall(data)

    def receive(self, command_id: int, n: int) -> list[Frame]:
        """Up to ``n`` frames with ``command_id`` (others are dropped: auto-updates of other IDs)."""
        got: list[Frame] = []
        deadline = time.monotonic() + self.timeout
        while len(got) < n:
            while self.frames and len(got) < n:
                f = self.frames.popleft()
                if f.command_id == command_id:
                    got.append(f)
            if len(got) >= n:
                break
            left = deadline - time.monotonic()
            if left <= 0:
                break
            self.sock.settimeout(min(left, IDLE_WAIT) if self.idle is not None else left)
            try:
                data = self.sock.recv(65536)
            except TimeoutError:
                if self.idle is not None:
                    self.idle()  # a manual clock: move time on so the motion can end
                    continue
                break
            if not data:
                break
            self.frames.extend(e for e in self.parser.feed(data) if isinstance(e, Frame))
        return got

    def close(self) -> None:
        self.sock.close()


def _compare(i: int, st: Step, rec: DecodedFrame, got: DecodedFrame, tol: float, out: list[Difference]) -> None:
    def diff(what: str, a: Any, b: Any) -> None:
        out.append(Difference(i, st.command, what, a, b))

    if rec.status_code != got.status_code:
        diff("status", rec.status, got.status)
        return
    if len(rec.raw) != len(got.raw) or [v.name for v in rec.values] != [v.name for v in got.values]:
        diff("layout", f"{len(rec.raw) - 8} payload bytes", f"{len(got.raw) - 8} payload bytes")
        return
    for a, b in zip(rec.values, got.values, strict=True):
        if isinstance(a.value, float) and isinstance(b.value, float):
            if not (math.isclose(a.value, b.value, abs_tol=tol) or (math.isnan(a.value) and math.isnan(b.value))):
                diff(a.name, a.text, b.text)
        elif a.value != b.value:
            diff(a.name, a.text, b.text)


def replay(path: str | Path, url: str, tolerance: float = 0.5, timeout: float = 10.0,
           idle: Callable[[], None] | None = None) -> ReplayReport:
    """Send the recorded requests of ``path`` to the gripper at ``url``; compare what comes back.

    ``tolerance``: largest difference of a measured (floating-point) value, in the field's unit.
    ``timeout``: longest wait for one request's replies, s (a motion's final reply included).
    ``idle``: called whenever no reply came for ``IDLE_WAIT`` s (a host moves a manual clock on).
    """
    steps = load_steps(path)
    report = ReplayReport(steps=len(steps))
    link = _Link(url, timeout, idle)
    try:
        for i, st in enumerate(steps, 1):
            if link.sock.fileno() < 0:  # the recorded client disconnected (07h) and came back
                link = _Link(url, timeout, idle)
            link.send(st.request)
            got = link.receive(st.command_id, len(st.replies))
            report.replies += len(got)
            for rec_raw, frame in zip(st.replies, got, strict=False):
                rec = decode_bytes(rec_raw, "reply")[0]
                _compare(i, st, rec, decode_frame(frame, "reply"), tolerance, report.differences)
            if len(got) < len(st.replies):
                report.differences.append(Difference(i, st.command, "replies", len(st.replies), len(got)))
            if st.command_id == Command.DISCONNECT and not link.udp:
                link.close()  # 000 §3.1.2: the gripper takes no more commands on this connection
    finally:
        link.close()
    return report
