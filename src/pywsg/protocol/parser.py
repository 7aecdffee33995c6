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
    """

    __slots__ = ("_buf", "max_payload", "verify_checksum")

    def __init__(self, verify_checksum: bool = True, max_payload: MaxPayload | None = None) -> None:
        self._buf = bytearray()
        self.verify_checksum = verify_checksum
        self.max_payload: MaxPayload = max_payload or _default_max

    @property
    def buffered(self) -> int:
        """Bytes held waiting for the rest of a frame (never more than one maximal frame)."""
        return len(self._buf)

    def pending(self) -> bytes:
        """The bytes held (for reporting a truncated tail)."""
        return bytes(self._buf)

    def clear(self) -> None:
        self._buf.clear()

    def feed(self, data: bytes | bytearray | memoryview) -> list[Event]:
        buf = self._buf
        if not buf:
            # the common case on a socket: nothing buffered and ``data`` is exactly one frame
            whole = whole_frame(data, self.verify_checksum, self.max_payload)
            if whole is not None:
                return [whole]
        buf += data
        events: list[Event] = []
        pos = 0
        n = len(buf)
        while True:
            start = buf.find(PREAMBLE, pos)
            if start < 0:
                # keep up to two trailing AAh: they may begin the next preamble
                keep = 0
                while keep < 2 and n - keep > pos and buf[n - keep - 1] == 0xAA:
                    keep += 1
                skipped = n - keep - pos
                if skipped:
                    events.append(GarbageSkipped(skipped))
                pos = n - keep
                break
            # In a run of AAh the preamble is its last three bytes: no command has ID AAh,
            # so a stray AAh before a frame costs one skipped byte, not a bogus header.
            while start + 3 < n and buf[start + 3] == 0xAA:
                start += 1
            if start > pos:
                events.append(GarbageSkipped(start - pos))
                pos = start
            if n - pos < HEADER_SIZE:
                break
            command_id, size = _SIZE.unpack_from(buf, pos + 3)
            limit = self.max_payload(command_id)
            if size > limit:
                events.append(FrameTooLarge(command_id, size, limit))
                pos += 1  # resynchronise on the next preamble
                continue
            end = pos + size + OVERHEAD
            if end > n:
                break
            if self.verify_checksum and crc16(memoryview(buf)[pos:end]) != 0:
                expected = crc16(memoryview(buf)[pos : end - 2])
                received = buf[end - 2] | (buf[end - 1] << 8)
                if expected != received:
                    events.append(
                        ChecksumMismatch(command_id, bytes(buf[pos + HEADER_SIZE : end - 2]), received, expected)
                    )
                    pos += 1  # a forged header must not swallow the frames behind it
                    continue
            events.append(Frame(command_id, bytes(buf[pos + HEADER_SIZE : end - 2])))
            pos = end
        if pos:
            del buf[:pos]
        return events

    def feed_all(self, chunks: Iterable[bytes]) -> list[Event]:
        out: list[Event] = []
        for chunk in chunks:
            out.extend(self.feed(chunk))
        return out


def parse_datagram(
    data: bytes, verify_checksum: bool = True, max_payload: MaxPayload | None = None
) -> list[Event]:
    """Parse one datagram (UDP: one frame per datagram). Leftovers are reported, never kept."""
    whole = whole_frame(data, verify_checksum, max_payload or _default_max)
    if whole is not None:
        return [whole]
    parser = FrameParser(verify_checksum, max_payload)
    events = parser.feed(data)
    rest = parser.pending()
    frames = [e for e in events if isinstance(e, Frame)]
    if rest and not frames:
        cid = rest[3] if len(rest) > 3 else None
        need = OVERHEAD
        if len(rest) >= HEADER_SIZE:
            need = OVERHEAD + (rest[4] | (rest[5] << 8))
        events.append(Truncated(cid, len(rest), need))
    elif rest:
        events.append(TrailingBytes(len(rest)))
    return events
