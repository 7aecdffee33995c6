"""Incremental, sans-IO frame parser.

Feed it bytes in any chunking; it returns complete :class:`Frame` objects and error events.
It skips bytes until a preamble, resynchronises after garbage, never buffers more than one
maximal frame (SIZE is capped per command ID before anything is waited for), and reports a
bad checksum as an event naming the command ID so a device can answer E_CHECKSUM_ERROR.

Hostile input costs bounded work. Every ``AA AA AA`` is a candidate header, and checking one means
a CRC over up to 1 KiB, so a stream of forged headers (``AA AA AA 99 00 04`` repeated) would cost
~170 CRC bytes per byte received and one error event each. A frame's own bytes pay for checking
it, so a frame - valid or not - that starts after the last failed one is always checked and reported
(the manual answers every frame). What costs without paying is a candidate *inside* the span of a
frame that already failed its checksum (a garbage candidate, checked only so that a forged header
cannot swallow the frames behind it), and a header whose SIZE is too large (a header, no frame). For
those the parser keeps an *error credit* (bytes): each byte fed earns one, at most
:data:`ERROR_CREDIT_BURST` is carried between feeds; such a candidate costs the bytes its CRC covered
plus :data:`ERROR_EVENT_COST` (the answer's cost). One that cannot be paid for is skipped as garbage
without a CRC and without an event (counted in :attr:`FrameParser.suppressed`). An honest link, even
one with corrupted frames, never runs short; a flood of forged headers costs about one CRC byte per
byte received and is answered about once per ``ERROR_EVENT_COST`` bytes.
"""

from __future__ import annotations

import collections
import itertools
import struct
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field

from .crc import PREAMBLE_CRC, crc16
from .frame import HEADER_SIZE, MAX_PAYLOAD, OVERHEAD, PREAMBLE, Frame

MaxPayload = Callable[[int], int]

ERROR_CREDIT_BURST = 16 * 1024
"""Error credit (bytes) a parser may hold: ~15 garbage candidates of maximal size in a row are checked."""
ERROR_EVENT_COST = 32
"""Credit (bytes) one paid-for error event costs on top of the CRC work (~ what answering it costs)."""


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


@dataclass(slots=True)
class Tally:
    """What :meth:`FrameParser.tally` counted of a feed, instead of one event per frame.

    ``frames``: valid frames per command ID; ``bad``: frames with a wrong checksum (``first_bad`` is
    the first of them); ``garbage``: bytes outside any frame (a failed frame's bytes after its
    preamble count here, as :meth:`FrameParser.feed` reports them); ``problems``: the other error
    events, in order.
    """

    frames: collections.Counter[int] = field(default_factory=collections.Counter)
    bad: int = 0
    first_bad: ChecksumMismatch | None = None
    garbage: int = 0
    problems: list[ParseError] = field(default_factory=list)

    def add(self, events: list[Event]) -> None:
        """Count ``events`` in."""
        for ev in events:
            if isinstance(ev, Frame):
                self.frames[ev.command_id] += 1
            elif isinstance(ev, ChecksumMismatch):
                self.bad += 1
                if self.first_bad is None:
                    self.first_bad = ev
            elif isinstance(ev, GarbageSkipped):
                self.garbage += ev.count
            else:
                self.problems.append(ev)


SPLIT_MIN_BYTES = 64
""":meth:`FrameParser.feed` splits a read of at least this many bytes (with nothing buffered) on the
preamble first: a run of whole frames costs one dict lookup each instead of a scan."""
_MEMO_SIZE = 256  # distinct pieces a parser remembers (then it forgets them all)
_MEMO_PIECE_BYTES = 64  # longer pieces are checked every time

TALLY_RESPLIT = 4
""":meth:`FrameParser.tally` splits again after an odd spot while it has split at most this many times
the bytes it was given; past that (odd spots everywhere), the rest is parsed the usual way."""


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


def _is_whole_frame(piece: bytes, max_payload: MaxPayload) -> bool:
    """``piece`` (what follows a preamble, up to the next) is one whole frame: ID (not AAh), SIZE,
    SIZE payload bytes (at most ``max_payload(ID)``) and the CRC."""
    n = len(piece)
    return n >= 5 and piece[0] != 0xAA and n == (piece[1] | (piece[2] << 8)) + 5 and n - 5 <= max_payload(piece[0])


class FrameParser:
    """Stream parser. ``feed(data)`` returns the frames and error events ``data`` completed.

    ``verify_checksum=False`` is the device's "CRC check disabled" setting: the checksum
    field must be present but its value is ignored. ``max_payload(command_id)`` bounds SIZE
    per ID (default: 1 KiB for every ID). Command ID AAh cannot be received: a fourth AAh
    is taken as garbage before the preamble.
    """

    __slots__ = ("_buf", "_credit", "_fail_end", "_memo", "_memo_verify", "max_payload", "suppressed",
                 "verify_checksum")

    _split_min = SPLIT_MIN_BYTES

    def __init__(self, verify_checksum: bool = True, max_payload: MaxPayload | None = None) -> None:
        self._buf = bytearray()
        self.verify_checksum = verify_checksum
        self.max_payload: MaxPayload = max_payload or _default_max
        self._credit = ERROR_CREDIT_BURST
        self._fail_end = 0  # end (in _buf) of the last frame that failed its checksum
        self.suppressed = 0
        """Candidate headers skipped unchecked because the error credit was spent (see module doc)."""
        self._memo: dict[bytes, tuple[Event, ...]] = {}  # piece after a preamble -> its events
        self._memo_verify = verify_checksum

    @property
    def buffered(self) -> int:
        """Bytes held waiting for the rest of a frame (never more than one maximal frame)."""
        return len(self._buf)

    def pending(self) -> bytes:
        """The bytes held (for reporting a truncated tail)."""
        return bytes(self._buf)

    def clear(self) -> None:
        self._buf.clear()
        self._fail_end = 0

    def feed(self, data: bytes | bytearray | memoryview) -> list[Event]:
        buf = self._buf
        if not buf:
            # the common case on a socket: nothing buffered and ``data`` is exactly one frame
            whole = whole_frame(data, self.verify_checksum, self.max_payload)
            if whole is not None:
                return [whole]
        if len(buf) + len(data) >= self._split_min and not self._fail_end:
            # many frames at once (a read cuts them anywhere: the buffered start of one joins the rest)
            stream = bytes(buf) + bytes(data) if buf else bytes(data)
            events, done = self._split_frames(stream)
            if done:
                if done == len(stream):
                    buf.clear()
                    self._credit = min(self._credit + len(data), ERROR_CREDIT_BURST)
                    return events
                # the rest is scanned with all the credit this feed earned, as without the split
                self._credit += len(data)
                buf[:] = memoryview(stream)[done:]
                more, pos = self._scan(0, 0)
                if pos:
                    del buf[:pos]
                events += more
                return events
        buf += data
        events, pos = self._scan(len(data), 0)
        if pos:
            del buf[:pos]
        return events

    def _split_frames(self, data: bytes) -> tuple[list[Event], int]:
        """The events of the run of whole frames ``data`` starts with, and the bytes they span.

        A read holding many frames back to back (a client pipelining, a flood) is split on the
        preamble in C; a piece between two preambles that is one whole frame (ID not AAh, SIZE within
        the cap, SIZE bytes of payload and the CRC) gives exactly the events :meth:`_scan` would: the
        frame, or a checksum failure and the garbage it leaves (a piece holds no preamble, so the scan
        resumes at the next one). Each distinct short piece is checked once (``_memo``). The run leaves
        its last piece to the scan if that piece failed (the scan may merge its garbage with what
        follows, or keep a trailing AAh), and ends before an odd spot or a partial frame.
        """
        if not data.startswith(PREAMBLE):
            return [], 0
        if self._memo_verify != self.verify_checksum:  # the device's CRC check was switched
            self._memo.clear()
            self._memo_verify = self.verify_checksum
        memo = self._memo
        events: list[Event] = []
        failed: list[Event] = []  # failures after the last valid frame, not yet in ``events``
        done = failed_bytes = last_failed = 0
        pieces = data.split(PREAMBLE)
        for piece in itertools.islice(pieces, 1, None):
            evs = memo.get(piece)
            if evs is None:
                evs = self._whole_piece(piece)
                if evs is None:
                    break
                if len(piece) <= _MEMO_PIECE_BYTES:
                    if len(memo) >= _MEMO_SIZE:
                        memo.clear()
                    memo[piece] = evs
            if len(evs) == 1:  # a valid frame
                if failed:
                    events += failed
                    failed = []
                events.append(evs[0])
                done += failed_bytes + 3 + len(piece)
                failed_bytes = 0
            else:
                failed += evs
                failed_bytes += 3 + len(piece)
                last_failed = 3 + len(piece)
        if failed:  # all but the last failure: the piece after each began at a preamble
            events += failed[:-2]
            done += failed_bytes - last_failed
        return events, done

    def _whole_piece(self, piece: bytes) -> tuple[Event, ...] | None:
        """``piece`` (what follows a preamble, up to the next) as one whole frame's events, or None."""
        if not _is_whole_frame(piece, self.max_payload):
            return None
        received = piece[-2] | (piece[-1] << 8)
        expected = crc16(memoryview(piece)[:-2], PREAMBLE_CRC) if self.verify_checksum else received
        if expected == received:
            return (Frame(piece[0], piece[3:-2]),)
        return ChecksumMismatch(piece[0], piece[3:-2], received, expected), GarbageSkipped(len(piece) + 2)

    def tally(self, data: bytes | bytearray | memoryview) -> Tally:
        """Like :meth:`feed` (the same frames, errors and state afterwards), for a caller that needs
        only how many frames of each kind ``data`` completed (a tap counting what it does not show).

        The bytes are split on the preamble (in C): a run of pieces that are each one whole frame - a
        flood, and most honest traffic - is counted in C, each distinct frame checked once. From an
        odd spot on, valid frames (say, with a preamble inside) are taken one by one; anything else
        (garbage, a failed frame with a preamble inside) is parsed the usual way up to the next
        frame boundary, then splitting resumes. Splitting again stops after :data:`TALLY_RESPLIT`
        times the input, so odd spots everywhere cost what :meth:`feed` costs, not more.
        """
        buf = self._buf
        rest = bytes(buf) + bytes(data) if buf else bytes(data)
        out = Tally()
        if (self._fail_end or not rest.startswith(PREAMBLE)
                or (not buf and whole_frame(data, self.verify_checksum, self.max_payload) is not None)):
            out.add(self.feed(data))
            return out
        earned = len(data)
        budget = TALLY_RESPLIT * len(rest)
        at = 0  # rest[at:] is still to do; it starts at a preamble, outside any failed frame
        while True:
            most = 0  # valid frames to take one by one next (0: all there are)
            if budget >= 0:
                budget -= len(rest) - at
                split_at = at
                at = self._count_plain(rest, at, out)
                most = 1 if at > split_at else 0  # odd spots close together: stay one by one
            # an odd spot (or the last frame): valid frames one by one
            before = at
            at = self._count_valid(rest, at, out, most)
            if at == len(rest) or budget < 0:
                break
            if at > before and rest.startswith(PREAMBLE, at):
                continue
            # the usual way, one event at a time, until the rest starts afresh at a preamble
            self._buf = bytearray(rest[at:])
            while True:
                if self._fail_end:  # after a failed frame: is the next candidate past its end?
                    start = self._buf.find(PREAMBLE)
                    if start >= self._fail_end:
                        out.garbage += start
                        del self._buf[:start]
                        self._fail_end = 0
                        break
                events, pos = self._scan(earned, 1, keep_credit=True)
                earned = 0
                del self._buf[:pos]
                out.add(events)
                if not pos or not self._buf:  # a partial frame waits, or nothing is left
                    self._credit = min(self._credit, ERROR_CREDIT_BURST)
                    return out
                if not self._fail_end and self._buf.startswith(PREAMBLE):
                    break
            rest, at = bytes(self._buf), 0
        self._buf = bytearray(rest[at:])
        events, pos = self._scan(earned, 0)
        if pos:
            del self._buf[:pos]
        out.add(events)
        return out

    def _count_plain(self, rest: bytes, at: int, out: Tally) -> int:
        """Count the run of pieces from ``rest[at:]`` (split on the preamble) that are each one whole
        frame, in C; returns where the run ends (the last piece, maybe partial, is never counted)."""
        # pieces[0] is b"". A piece cannot end in AAh (the preamble would have matched a byte earlier),
        # so the usual scan, resuming after a failed frame, finds the next preamble where the split did.
        pieces = rest[at:].split(PREAMBLE)
        end = len(pieces) - 1
        counts = collections.Counter(pieces[1:end])  # keys in order of first appearance
        limit = self.max_payload
        odd = next((p for p in counts if not _is_whole_frame(p, limit)), None)
        if odd is not None:
            end = pieces.index(odd, 1)
            counts = collections.Counter(pieces[1:end])
        verify = self.verify_checksum
        for piece, n in counts.items():
            received = piece[-2] | (piece[-1] << 8)
            expected = crc16(memoryview(piece)[:-2], PREAMBLE_CRC) if verify else received
            if expected == received:
                out.frames[piece[0]] += n
            else:
                out.bad += n
                out.garbage += n * (len(piece) + 2)  # a failed frame's bytes after its first one
                if out.first_bad is None:
                    out.first_bad = ChecksumMismatch(piece[0], piece[3:-2], received, expected)
        return at + 3 * (end - 1) + sum(map(len, pieces[1:end]))

    def _count_valid(self, rest: bytes, at: int, out: Tally, most: int) -> int:
        """Count valid frames back to back from ``rest[at:]`` (at most ``most``, 0: no limit), as the
        usual scan would take them; returns where the first thing that is not one begins."""
        n = len(rest)
        limit = self.max_payload
        verify = self.verify_checksum
        frames = out.frames
        seen = 0
        while rest.startswith(PREAMBLE, at) and at + HEADER_SIZE <= n:
            command_id, size = _SIZE.unpack_from(rest, at + 3)
            end = at + size + OVERHEAD
            if command_id == 0xAA or size > limit(command_id) or end > n:
                break
            if verify and crc16(memoryview(rest)[at + 3 : end], PREAMBLE_CRC) != 0:
                break
            frames[command_id] += 1
            at = end
            seen += 1
            if seen == most:
                break
        return at

    def _scan(self, earned: int, stop_after: int, keep_credit: bool = False) -> tuple[list[Event], int]:
        """Parse ``self._buf``; returns the events and how many bytes were consumed.

        ``earned``: error credit the new bytes bring. ``stop_after``: stop after this many frames or
        error events (0: no limit) - a datagram holds one frame. ``keep_credit``: the scan goes on in
        another call for the same feed (do not cap the credit at the burst yet).
        """
        buf = self._buf
        credit = self._credit + earned  # capped at the burst between feeds
        fail_end = self._fail_end
        events: list[Event] = []
        answered = 0
        pos = 0
        skipped = 0  # garbage not reported yet: one event per run, not one per candidate
        n = len(buf)
        max_payload = self.max_payload
        while True:
            if stop_after and answered >= stop_after:
                break
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
                pos += 1  # resynchronise on the next preamble
                if credit < ERROR_EVENT_COST:
                    self.suppressed += 1
                    skipped += 1
                    continue
                credit -= ERROR_EVENT_COST
                if skipped:
                    events.append(GarbageSkipped(skipped))
                    skipped = 0
                events.append(FrameTooLarge(command_id, size, limit))
                skipped = 0
                answered += 1
                continue
            end = pos + size + OVERHEAD
            if end > n:
                break
            if self.verify_checksum:
                inside = pos < fail_end  # a garbage candidate: its bytes belong to a failed frame
                if inside and credit < end - pos + ERROR_EVENT_COST:
                    # a flood of failing candidates spent the credit: do not CRC what is most
                    # likely one more forged header (a valid frame after the flood is checked again)
                    self.suppressed += 1
                    skipped += 1
                    pos += 1
                    continue
                expected = crc16(memoryview(buf)[pos : end - 2])
                received = buf[end - 2] | (buf[end - 1] << 8)
                if expected != received:
                    if inside:
                        credit -= end - pos + ERROR_EVENT_COST
                    if end > fail_end:
                        fail_end = end
                    if skipped:
                        events.append(GarbageSkipped(skipped))
                    events.append(
                        ChecksumMismatch(command_id, bytes(buf[pos + HEADER_SIZE : end - 2]), received, expected)
                    )
                    answered += 1
                    skipped = 0
                    pos += 1  # a forged header must not swallow the frames behind it
                    continue
            if skipped:
                events.append(GarbageSkipped(skipped))
                skipped = 0
            events.append(Frame(command_id, bytes(buf[pos + HEADER_SIZE : end - 2])))
            answered += 1
            pos = end
        if skipped:
            events.append(GarbageSkipped(skipped))
        self._credit = max(0, credit if keep_credit else min(credit, ERROR_CREDIT_BURST))
        self._fail_end = max(0, fail_end - pos)
        return events, pos

    def feed_all(self, chunks: Iterable[bytes]) -> list[Event]:
        out: list[Event] = []
        for chunk in chunks:
            out.extend(self.feed(chunk))
        return out


def parse_datagram(
    data: bytes, verify_checksum: bool = True, max_payload: MaxPayload | None = None
) -> list[Event]:
    """Parse one datagram: **one frame per datagram** (UDP). Leftovers are reported, never kept.

    Only the first frame (or the first error: bad CRC, SIZE too large, truncated) is returned; the
    bytes after it are one :class:`TrailingBytes` event, not parsed. So a datagram gets at most one
    answer however many frames or forged headers it holds (no amplification), and its cost is one
    CRC at most.
    """
    whole = whole_frame(data, verify_checksum, max_payload or _default_max)
    if whole is not None:
        return [whole]
    parser = FrameParser(verify_checksum, max_payload)
    parser._buf += data
    events, pos = parser._scan(len(data), stop_after=1)
    rest = len(data) - pos
    answered = any(not isinstance(e, GarbageSkipped) for e in events)
    if rest and not answered:
        tail = data[pos:]
        cid = tail[3] if len(tail) > 3 else None
        need = OVERHEAD
        if len(tail) >= HEADER_SIZE:
            need = OVERHEAD + (tail[4] | (tail[5] << 8))
        events.append(Truncated(cid, len(tail), need))
    elif rest:
        events.append(TrailingBytes(rest))
    return events
