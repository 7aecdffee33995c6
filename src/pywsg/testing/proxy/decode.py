"""The decoding side of ``wsg proxy``: frames out of each direction of each connection, into the comm log.

Decoding comes after forwarding and runs in chunks on a task of its own, so a flood never holds up the
relay or the other clients (docs/sim.md "Bounds").
"""

from __future__ import annotations

import asyncio
import collections
from collections.abc import Callable
from typing import Any, Protocol

from ...capture.commlog import CommLog, TxRx
from ...protocol import ChecksumMismatch, Frame, FrameParser, GarbageSkipped
from ...protocol.parser import Tally, parse_datagram
from .capture import LogGate, ProxyStats

__all__ = ["DECODE_BACKLOG", "DECODE_CHUNK", "LOG_CHUNK", "LOG_CHUNK_MAX", "Decoder", "Recorder"]

DECODE_BACKLOG = 1024 * 1024
"""Bytes waiting to be decoded at which reading from that side pauses."""
DECODE_CHUNK = 8 * 1024
"""Bytes decoded per turn of the event loop while the log shows no frames (over ``log_rate``): counted
in bulk (:meth:`~pywsg.protocol.FrameParser.tally`), about 0.1 ms per turn."""
LOG_CHUNK = 256
"""Bytes decoded per turn of the event loop while frames are shown: each shown frame is decoded and
formatted (tens of µs), so a turn stays about a millisecond. A turn that showed next to nothing
(stray bytes, long frames) doubles the next one, up to :data:`LOG_CHUNK_MAX`."""
LOG_CHUNK_MAX = 2048
"""Bytes decoded per turn at most while frames are shown (at most 256 small frames, ~10 ms)."""


class Recorder(Protocol):
    """Where a :class:`Decoder` reports (the :class:`~pywsg.testing.proxy.Proxy`)."""

    stats: ProxyStats
    gate: LogGate
    log: CommLog | None
    _tasks: set[asyncio.Task[Any]]


class Decoder:
    """Frames out of one direction of one connection, into the comm log.

    Decodes on a task of its own, :data:`DECODE_CHUNK` bytes per loop turn, so a flood never holds up
    the loop; ``hold(True)`` is called while :data:`DECODE_BACKLOG` bytes wait (the caller pauses
    reading), ``hold(False)`` once half of it is done.
    """

    def __init__(self, proxy: Recorder, direction: TxRx, hold: Callable[[bool], None] | None = None) -> None:
        self.parser = FrameParser(verify_checksum=True)
        self.proxy = proxy
        self.direction: TxRx = direction
        self.stats = proxy.stats
        self.hold = hold
        self.backlog: collections.deque[tuple[bytes, bool]] = collections.deque()
        self.waiting = 0
        self.held = False
        self.dropped = 0  # datagrams not decoded: the backlog was full (UDP cannot pause)
        self.task: asyncio.Task[None] | None = None
        self.step = LOG_CHUNK  # bytes decoded in the next turn while frames are shown

    def feed(self, data: bytes, datagram: bool = False) -> None:
        self.stats.bytes[self.direction] += len(data)
        if self.waiting >= DECODE_BACKLOG and self.hold is None:
            self.dropped += 1
            return
        self.backlog.append((data, datagram))
        self.waiting += len(data)
        if self.waiting >= DECODE_BACKLOG and self.hold is not None and not self.held:
            self.held = True
            self.hold(True)
        if self.task is None:
            self.task = asyncio.get_running_loop().create_task(self._run())
            self.proxy._tasks.add(self.task)
            self.task.add_done_callback(self.proxy._tasks.discard)

    async def _run(self) -> None:
        gate = self.proxy.gate
        try:
            while self.backlog:
                data, datagram = self.backlog.popleft()
                if datagram:
                    self._events(parse_datagram(data))
                else:
                    i = 0
                    while i < len(data):
                        if gate.full():  # nothing is shown: count the frames in bulk
                            part = data[i : i + DECODE_CHUNK]
                            self._tally(self.parser.tally(part))
                        else:
                            part = data[i : i + self.step]
                            used = gate.used
                            self._events(self.parser.feed(part))
                            few = 0 <= gate.used - used <= 2  # (a new second starts at 0: also few)
                            self.step = min(2 * self.step, LOG_CHUNK_MAX) if few else LOG_CHUNK
                        i += len(part)
                        if i < len(data):
                            await asyncio.sleep(0)
                self.waiting -= len(data)
                if self.held and self.waiting <= DECODE_BACKLOG // 2 and self.hold is not None:
                    self.held = False
                    self.hold(False)
                await asyncio.sleep(0)
        finally:
            self.task = None

    async def drain(self) -> None:
        """Wait until everything fed so far is decoded."""
        while self.task is not None:
            await asyncio.sleep(0)

    def _tally(self, t: Tally) -> None:
        """Frames counted in bulk (none of them shown); stream problems as in :meth:`_events`."""
        direction = self.direction
        if t.frames:
            self.stats.frames[direction] += sum(t.frames.values())
            for cid, n in t.frames.items():
                self.proxy.gate.skip(direction, f"{cid:02X}h", n)
        first = ""
        if t.first_bad is not None:
            ev = t.first_bad
            first = f"first {ev.command_id:02X}h: {ev.received:04X}h, expected {ev.expected:04X}h"
        self._events(t.problems, t.bad, t.garbage, first)

    def _events(self, events: list[Any], bad: int = 0, garbage: int = 0, first: str = "") -> None:
        """Frames into the log (as the gate allows); stream problems, with ``bad`` checksum failures and
        ``garbage`` bytes counted before, as one note."""
        gate, log, direction = self.proxy.gate, self.proxy.log, self.direction
        other = 0
        for ev in events:
            if isinstance(ev, Frame):
                self.stats.frames[direction] += 1
                if log is not None and gate.allow(direction, f"{ev.command_id:02X}h"):
                    log.record(direction, ev)
            elif isinstance(ev, ChecksumMismatch):
                bad += 1
                first = first or (f"first {ev.command_id:02X}h: {ev.received:04X}h, expected {ev.expected:04X}h")
            elif isinstance(ev, GarbageSkipped):
                garbage += ev.count
            else:
                other += 1
                first = first or type(ev).__name__
        # one note for them all; over the rate, the frames with a wrong checksum are counted as left out
        if (bad or garbage or other) and log is not None and gate.allow(
                direction, "wrong checksum" if bad else "stream problems", bad or 1):
            parts = []
            if bad:
                parts.append(f"{bad} frame(s) with a wrong checksum")
            if garbage:
                parts.append(f"{garbage} byte(s) outside any frame")
            if other:
                parts.append(f"{other} other problem(s)")
            log.note(direction, ", ".join(parts) + (f" ({first})" if first else ""))
