"""Incremental, sans-IO frame parser.

Feed it bytes in any chunking; it returns complete :class:`Frame` objects and error events.
It skips bytes until a preamble, resynchronises after garbage, never buffers more than one
maximal frame (SIZE is capped per command ID before anything is waited for), and reports a
bad checksum as an event naming the command ID so a device can answer E_CHECKSUM_ERROR.
"""

from __future__ import annotations

import struct
from collections.abc import Callable, Iterable
from dataclasses import dataclass

from .crc import crc16
from .crc_window import RunningCrc
from .frame import HEADER_SIZE, MAX_PAYLOAD, OVERHEAD, PREAMBLE, Frame

MaxPayload = Callable[[int], int]


def _default_max(_command_id: int) -> int:
    return MAX_PAYLOAD


@dataclass(frozen=True, slots=True)
class ParseError:
    """Base of the parser's error events."""

    @property
    def message(self) -> str:
        raise NotImplementedError


@dataclass(frozen=True, slots=True)
class GarbageSkipped(ParseError):
    """``count`` bytes before a preamble were dropped."""

    count: int

    @property
    def message(self) -> str:
        return f"skipped {self.count} byte(s) before a preamble"


@dataclass(frozen=True, slots=True)
class ChecksumMismatch(ParseError):
    """A complete frame whose CRC is wrong. The frame is not delivered."""

    command_id: int
    payload: bytes
    received: int
    expected: int

    @property
    def message(self) -> str:
        return (
            f"checksum error in frame {self.command_id:02X}h: received {self.received:04X}h, "
            f"expected {self.expected:04X}h"
        )


@dataclass(frozen=True, slots=True)
class FrameTooLarge(ParseError):
    """A header announced more payload than ``command_id`` can take; nothing was waited for."""

    command_id: int
    size: int
    limit: int

    @property
    def message(self) -> str:
        return f"frame {self.command_id:02X}h announces {self.size} payload bytes, at most {self.limit} allowed"


@dataclass(frozen=True, slots=True)
class Truncated(ParseError):
    """A datagram (or the end of input) held only part of a frame."""

    command_id: int | None
    have: int
    need: int

    @property
    def message(self) -> str:
        cid = "?" if self.command_id is None else f"{self.command_id:02X}h"
        return f"truncated frame {cid}: {self.have} of {self.need} bytes"


@dataclass(frozen=True, slots=True)
class TrailingBytes(ParseError):
    """A datagram held bytes after its frame."""

    count: int

    @property
    def message(self) -> str:
        return f"{self.count} byte(s) after the frame in one datagram"


Event = Frame | ParseError
_SIZE = struct.Struct("<BH")


def whole_frame(data: bytes | bytearray | memoryview, verify_checksum: bool, max_payload: MaxPayload) -> Frame | None:
    """``data`` as one valid frame, or None if it is anything else (then parse it the long way).

    The fast path for a socket read or a datagram holding exactly one frame: the CRC over a whole
    frame, checksum included, is 0.
    """
    n = len(data)
    if n < OVERHEAD or data[0] != 0xAA or data[1] != 0xAA or data[2] != 0xAA:
        return None
    command_id = data[3]
    size = data[4] | (data[5] << 8)
    if (n == size + OVERHEAD and command_id != 0xAA and size <= max_payload(command_id)
            and (not verify_checksum or crc16(data) == 0)):
        return Frame(command_id, bytes(data[HEADER_SIZE:-2]))
    return None


class FrameParser:
    """Stream parser. ``feed(data)`` returns the frames and error events ``data`` completed.

    ``verify_checksum=False`` is the device's "CRC check disabled" setting: the checksum
    field must be present but its value is ignored. ``max_payload(command_id)`` bounds SIZE
    per ID (default: 1 KiB for every ID). Command ID AAh cannot be received: a fourth AAh
    is taken as garbage before the preamble.

    Hostile input costs about what random bytes cost (docs/protocol.md, "Garbage and forged headers"):

    - A candidate header that fails is left one byte later (frames behind a forged header are never
      lost), so candidates overlap; a candidate inside the span of one already checked is verified from
      running CRC states (:class:`~.crc_window.RunningCrc`, two table look-ups) instead of a CRC of up
      to 1 KiB. Every byte is fed through the CRC at most twice.
    - One error per span: a checksum or size error is reported for a candidate only if it does not
      start inside the span (at most one maximal frame) of the last candidate that already got an
      error. Frames never overlap, so the later one cannot be a frame the sender sent: the manual asks
      for an answer per frame, not per garbage candidate. Its bytes count as skipped garbage. Valid
      frames are always delivered.
    - Runs of skipped garbage are reported as one :class:`GarbageSkipped` per feed.
    """

    __slots__ = ("_buf", "_quiet", "_running", "max_payload", "verify_checksum")

    def __init__(self, verify_checksum: bool = True, max_payload: MaxPayload | None = None) -> None:
        self._buf = bytearray()
        self.verify_checksum = verify_checksum
        self.max_payload: MaxPayload = max_payload or _default_max
        self._quiet = 0
        """Buffer index before which candidates get no error event (the span of the last error)."""
        self._running = RunningCrc()

    @property
    def buffered(self) -> int:
        """Bytes held waiting for the rest of a frame (never more than one maximal frame)."""
        return len(self._buf)

    def pending(self) -> bytes:
        """The bytes held (for reporting a truncated tail)."""
        return bytes(self._buf)

    def clear(self) -> None:
        self._buf.clear()
        self._quiet = 0
        self._running.clear()

    def feed(self, data: bytes | bytearray | memoryview) -> list[Event]:
        buf = self._buf
        if not buf:
            # the common case on a socket: nothing buffered and ``data`` is exactly one frame
            whole = whole_frame(data, self.verify_checksum, self.max_payload)
            if whole is not None:
                self._quiet = 0
                return [whole]
        buf += data
        events: list[Event] = []
        skipped = 0  # garbage not yet reported (one event per run)
        pos = 0
        n = len(buf)
        quiet = self._quiet
        running = self._running
        verify = self.verify_checksum
        max_payload = self.max_payload
        while True:
            start = buf.find(PREAMBLE, pos)
            if start < 0:
                # keep up to two trailing AAh: they may begin the next preamble
                keep = 0
                while keep < 2 and n - keep > pos and buf[n - keep - 1] == 0xAA:
                    keep += 1
                skipped += n - keep - pos
                pos = n - keep
                break
            # In a run of AAh the preamble is its last three bytes: no command has ID AAh,
            # so a stray AAh before a frame costs one skipped byte, not a bogus header.
            while start + 3 < n and buf[start + 3] == 0xAA:
                start += 1
            skipped += start - pos
            pos = start
            if n - pos < HEADER_SIZE:
                break
            command_id, size = _SIZE.unpack_from(buf, pos + 3)
            limit = max_payload(command_id)
            if size > limit:
                if pos < quiet:
                    skipped += 1
                else:
                    if skipped:
                        events.append(GarbageSkipped(skipped))
                        skipped = 0
                    events.append(FrameTooLarge(command_id, size, limit))
                    quiet = pos + min(size, MAX_PAYLOAD) + OVERHEAD
                pos += 1  # resynchronise on the next preamble
                continue
            end = pos + size + OVERHEAD
            if end > n:
                break
            if verify:
                received = buf[end - 2] | (buf[end - 1] << 8)
                # inside a span already checked, verify from running states (no CRC over the span again)
                expected = running.window(buf, pos, end - 2) if pos < quiet else crc16(memoryview(buf)[pos : end - 2])
                if expected != received:
                    if pos < quiet:
                        skipped += 1
                    else:
                        if skipped:
                            events.append(GarbageSkipped(skipped))
                            skipped = 0
                        events.append(
                            ChecksumMismatch(command_id, bytes(buf[pos + HEADER_SIZE : end - 2]), received, expected)
                        )
                        quiet = end
                    pos += 1  # a forged header must not swallow the frames behind it
                    continue
            if skipped:
                events.append(GarbageSkipped(skipped))
                skipped = 0
            events.append(Frame(command_id, bytes(buf[pos + HEADER_SIZE : end - 2])))
            pos = end
            quiet = 0  # in step with the sender again: the next bad frame is answered
        if skipped:
            events.append(GarbageSkipped(skipped))
        if pos:
            del buf[:pos]
            quiet = max(quiet - pos, 0)
            if quiet:
                running.drop(pos)
        if not quiet and len(running):
            running.clear()
        self._quiet = quiet
        return events

    def feed_all(self, chunks: Iterable[bytes]) -> list[Event]:
        out: list[Event] = []
        for chunk in chunks:
            out.extend(self.feed(chunk))
        return out


def parse_datagram(
    data: bytes, verify_checksum: bool = True, max_payload: MaxPayload | None = None
) -> list[Event]:
    """Parse one datagram: it holds one frame (UDP, docs/sim.md), so only its first candidate is read.

    Garbage before the preamble is reported; bytes after the frame are reported as
    :class:`TrailingBytes` and never parsed, so a datagram is answered at most once whatever it holds
    (no amplification) and costs at most one CRC over one frame. Nothing is kept.
    """
    limits = max_payload or _default_max
    whole = whole_frame(data, verify_checksum, limits)
    if whole is not None:
        return [whole]
    events: list[Event] = []
    n = len(data)
    start = data.find(PREAMBLE)
    if start < 0:
        if n:
            events.append(GarbageSkipped(n))
        return events
    while start + 3 < n and data[start + 3] == 0xAA:  # in a run of AAh the preamble is its last three
        start += 1
    if start:
        events.append(GarbageSkipped(start))
    have = n - start
    if have < HEADER_SIZE:
        events.append(Truncated(data[start + 3] if have > 3 else None, have, OVERHEAD))
        return events
    command_id, size = _SIZE.unpack_from(data, start + 3)
    limit = limits(command_id)
    if size > limit:
        events.append(FrameTooLarge(command_id, size, limit))
        return events
    end = start + size + OVERHEAD
    if end > n:
        events.append(Truncated(command_id, have, size + OVERHEAD))
        return events
    received = data[end - 2] | (data[end - 1] << 8)
    expected = crc16(memoryview(data)[start : end - 2]) if verify_checksum else received
    if expected != received:
        events.append(ChecksumMismatch(command_id, bytes(data[start + HEADER_SIZE : end - 2]), received, expected))
    else:
        events.append(Frame(command_id, bytes(data[start + HEADER_SIZE : end - 2])))
    if end < n:
        events.append(TrailingBytes(n - end))
    return events
