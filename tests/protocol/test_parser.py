"""The incremental parser: chunking, resynchronisation, caps, checksum events, datagrams."""

from __future__ import annotations

import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from pywsg.protocol import (
    MAX_PAYLOAD,
    ChecksumMismatch,
    Frame,
    FrameParser,
    FrameTooLarge,
    GarbageSkipped,
    ParseError,
    TrailingBytes,
    Truncated,
    encode_frame,
    parse_datagram,
)
from pywsg.protocol.catalog import request_max_payload
from pywsg.protocol.parser import ERROR_CREDIT_BURST, ERROR_EVENT_COST, Tally

HOMING_OK = bytes.fromhex("AAAAAA2002000000B3FD")


def frames_of(events: list[Frame | ParseError]) -> list[Frame]:
    return [e for e in events if isinstance(e, Frame)]


def test_byte_by_byte() -> None:
    p = FrameParser()
    out: list[Frame | ParseError] = []
    for b in HOMING_OK:
        out += p.feed(bytes([b]))
    assert out == [Frame(0x20, b"\x00\x00")]
    assert p.buffered == 0


def test_garbage_before_preamble_is_skipped_and_reported() -> None:
    events = FrameParser().feed(b"\x01\x02\x03" + HOMING_OK)
    assert events == [GarbageSkipped(3), Frame(0x20, b"\x00\x00")]


def test_extra_aa_before_preamble_resynchronises() -> None:
    # AA AA AA AA 20 ...: the first AA starts a bogus frame whose checksum fails; the real one follows
    events = FrameParser().feed(b"\xaa\xaa" + HOMING_OK)
    assert events == [GarbageSkipped(2), Frame(0x20, b"\x00\x00")]


def test_bad_checksum_names_the_command() -> None:
    bad = bytearray(encode_frame(0x21, b"\x00" * 9))
    bad[-1] ^= 0xFF
    events = FrameParser().feed(bytes(bad))
    mism = [e for e in events if isinstance(e, ChecksumMismatch)]
    assert len(mism) == 1
    assert mism[0].command_id == 0x21
    assert mism[0].expected == bad[-2] | ((bad[-1] ^ 0xFF) << 8)
    assert not frames_of(events)
    assert "21h" in mism[0].message


def test_checksum_ignored_when_disabled() -> None:
    bad = encode_frame(0x22)[:-2] + b"\x00\x00"
    assert FrameParser(verify_checksum=False).feed(bad) == [Frame(0x22, b"")]


def test_forged_size_is_rejected_without_waiting_or_allocating() -> None:
    p = FrameParser(max_payload=request_max_payload)
    events = p.feed(b"\xaa\xaa\xaa\x20\xff\xff")  # HOMING with SIZE 65535
    assert events[0] == FrameTooLarge(0x20, 0xFFFF, 1)
    assert p.buffered <= 2
    # the stream goes on: a valid request right after is still delivered
    assert frames_of(p.feed(encode_frame(0x20, b"\x01"))) == [Frame(0x20, b"\x01")]


def test_size_cap_for_unknown_ids_is_1kib() -> None:
    p = FrameParser(max_payload=request_max_payload)
    events = p.feed(b"\xaa\xaa\xaa\x90" + (MAX_PAYLOAD + 1).to_bytes(2, "little"))
    assert events == [FrameTooLarge(0x90, MAX_PAYLOAD + 1, MAX_PAYLOAD), GarbageSkipped(5)]


def test_frames_inside_a_forged_header_are_not_lost() -> None:
    # a forged header announces 20 bytes; a real frame starts inside them
    forged = b"\xaa\xaa\xaa\x06\x14\x00"
    events = FrameParser().feed(forged + HOMING_OK + b"\x00" * 12)
    assert frames_of(events) == [Frame(0x20, b"\x00\x00")]


def test_datagram_one_frame() -> None:
    assert parse_datagram(HOMING_OK) == [Frame(0x20, b"\x00\x00")]


def test_datagram_truncated_and_trailing() -> None:
    assert parse_datagram(HOMING_OK[:-1]) == [Truncated(0x20, 9, 10)]
    assert parse_datagram(b"") == []
    events = parse_datagram(HOMING_OK + b"\x01\x02")
    assert events[0] == Frame(0x20, b"\x00\x00")
    assert any(isinstance(e, GarbageSkipped | TrailingBytes) for e in events[1:])


valid_frames = st.builds(
    lambda cid, payload: (cid, payload),
    st.integers(0, 255).filter(lambda i: i != 0xAA),  # AAh is not a command ID
    st.binary(max_size=64),
)
aa_free_garbage = st.binary(max_size=40).map(lambda b: b.replace(b"\xaa", b"\x55"))


@settings(max_examples=200, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(st.tuples(aa_free_garbage, valid_frames), max_size=6), aa_free_garbage, st.data())
def test_garbage_free_of_aa_never_loses_a_frame(pairs, tail, data) -> None:  # type: ignore[no-untyped-def]
    stream = b"".join(g + encode_frame(cid, pl) for g, (cid, pl) in pairs) + tail
    cuts = sorted(data.draw(st.lists(st.integers(0, len(stream)), max_size=8)))
    chunks = [stream[a:b] for a, b in zip([0, *cuts], [*cuts, len(stream)], strict=True)]
    p = FrameParser()
    got = frames_of(p.feed_all(chunks))
    assert got == [Frame(cid, pl) for _, (cid, pl) in pairs]


@settings(max_examples=300, suppress_health_check=[HealthCheck.too_slow])
@given(
    st.lists(
        st.one_of(
            st.binary(max_size=50),
            st.just(b"\xaa\xaa\xaa"),
            st.builds(lambda i, n: b"\xaa\xaa\xaa" + bytes([i]) + n.to_bytes(2, "little"),
                      st.integers(0, 255), st.integers(0, 0xFFFF)),
        ),
        max_size=10,
    ),
    valid_frames,
    st.integers(1, 64),
)
# Found by Hypothesis: the forged 89h header announces 333 bytes; the good frame and the zero padding fill them
# and the CRC passes, so a real 89h frame swallows the good one (000 §1.2: any receiver would take it).
@example(garbage_parts=[b"\xaa\xaa\xaa\x89M\x01"], frame=(0, b""), chunk=1)
def test_arbitrary_garbage_is_bounded_and_recovers(garbage_parts, frame, chunk) -> None:  # type: ignore[no-untyped-def]
    garbage = b"".join(garbage_parts)
    cid, payload = frame
    good = encode_frame(cid, payload)
    p = FrameParser(max_payload=request_max_payload)
    seen: list[Frame | ParseError] = []
    stream = garbage + good
    for i in range(0, len(stream), chunk):
        seen += p.feed(stream[i : i + chunk])
        assert p.buffered <= MAX_PAYLOAD + 8 + chunk
        assert all(isinstance(e, Frame | ParseError) for e in seen)
    # once enough bytes have arrived (a forged header may still be waiting), the frame comes out
    padding = b"\x00" * (MAX_PAYLOAD + 8)
    seen += p.feed(padding)
    if request_max_payload(cid) >= len(payload):
        got = frames_of(seen)
        # A forged header in the garbage whose frame happens to pass the 16-bit CRC (1 in 65,536) is a real
        # frame to any receiver, and it may swallow the good one: then that frame starts in the garbage and
        # reaches past it (into the good frame, and maybe into the padding that completed it).
        sent = stream + padding
        swallowed = [f for f in got if f != Frame(cid, payload) and f.encode() in sent
                     and sent.find(f.encode()) < len(garbage) < sent.find(f.encode()) + len(f.encode())]
        assert Frame(cid, payload) in got or swallowed


# -- hostile input: bounded work (docs/sim.md "Hostile input", docs/fidelity.md) ----------------

FORGED_1K = b"\xaa\xaa\xaa\x99\x00\x04"  # unknown ID announcing 1 KiB: every 6 bytes a CRC candidate


def crc_bytes_counted(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    import pywsg.protocol.parser as parser_module

    counted = [0]
    real = parser_module.crc16

    def counting(data: bytes | bytearray | memoryview, crc: int = 0xFFFF) -> int:
        counted[0] += len(data)
        return real(data, crc)

    monkeypatch.setattr(parser_module, "crc16", counting)
    return counted


def test_forged_header_flood_costs_about_one_crc_byte_per_byte(monkeypatch: pytest.MonkeyPatch) -> None:
    counted = crc_bytes_counted(monkeypatch)
    flood = FORGED_1K * 20_000  # 120 KB: ~20,000 candidates of 1 KiB each (~20 MB of CRC before)
    p = FrameParser(max_payload=request_max_payload)
    events = [e for i in range(0, len(flood), 4096) for e in p.feed(flood[i : i + 4096])]
    assert counted[0] <= 2 * len(flood) + ERROR_CREDIT_BURST
    errors = [e for e in events if isinstance(e, ChecksumMismatch)]
    assert 0 < len(errors) < 20_000 // 20
    assert p.suppressed > 15_000
    # the flood ends: padding completes the waiting header, and a real frame is delivered
    assert frames_of(p.feed(bytes(2100) + encode_frame(0x20, b"\x01"))) == [Frame(0x20, b"\x01")]


def test_every_complete_bad_frame_is_answered_however_many() -> None:
    """000 §1.2.2: every frame is acknowledged - frames with bad CRCs that do not overlap are frames."""
    bad = encode_frame(0x06, b"xyz")[:-2] + b"\x00\x00"
    events = FrameParser().feed(bad * 5000)
    assert sum(isinstance(e, ChecksumMismatch) for e in events) == 5000


def test_honest_stream_with_corrupted_frames_loses_no_answer() -> None:
    good = encode_frame(0x06, bytes(range(0x20, 0xA0)) * 8)  # 1 KiB payload, no AAh
    bad = good[:-2] + bytes([good[-2] ^ 1, good[-1]])
    stream = (bad + good) * 40
    events = FrameParser().feed_all([stream[i : i + 1500] for i in range(0, len(stream), 1500)])
    assert sum(isinstance(e, ChecksumMismatch) for e in events) == 40
    assert len(frames_of(events)) == 40


def test_size_too_large_flood_is_answered_rate_limited() -> None:
    p = FrameParser(max_payload=request_max_payload)
    events = p.feed(b"\xaa\xaa\xaa\x20\xff\xff" * 20_000)
    n = sum(isinstance(e, FrameTooLarge) for e in events)
    assert ERROR_CREDIT_BURST // ERROR_EVENT_COST <= n <= (ERROR_CREDIT_BURST + 120_000) // ERROR_EVENT_COST + 1
    assert frames_of(p.feed(encode_frame(0x20, b"\x01"))) == [Frame(0x20, b"\x01")]


def test_datagram_answers_its_first_frame_only(monkeypatch: pytest.MonkeyPatch) -> None:
    events = parse_datagram(b"".join(encode_frame(0x06, bytes([i])) for i in range(50)))
    assert events[0] == Frame(0x06, b"\x00")
    assert [type(e) for e in events[1:]] == [TrailingBytes]
    counted = crc_bytes_counted(monkeypatch)
    events = parse_datagram(FORGED_1K * 10_000)
    assert sum(not isinstance(e, GarbageSkipped | TrailingBytes) for e in events) == 1
    assert counted[0] <= 1100  # one candidate checked


def _as_tally(events: list[Frame | ParseError]) -> tuple[dict[int, int], int, int, list[str]]:
    """(valid frames per ID, bad frames, garbage bytes, other events) of a list of events."""
    frames: dict[int, int] = {}
    bad = garbage = 0
    other = []
    for e in events:
        if isinstance(e, Frame):
            frames[e.command_id] = frames.get(e.command_id, 0) + 1
        elif isinstance(e, ChecksumMismatch):
            bad += 1
        elif isinstance(e, GarbageSkipped):
            garbage += e.count
        else:
            other.append(repr(e))
    return frames, bad, garbage, other


stream_parts = st.one_of(
    valid_frames.map(lambda f: encode_frame(*f)),
    valid_frames.map(lambda f: encode_frame(*f)[:-2] + b"\0\0"),  # a bad CRC (or, rarely, a valid one)
    st.binary(max_size=12),
    st.sampled_from([b"\xaa", b"\xaa\xaa", b"\xaa\xaa\xaa", b"\xaa\xaa\xaa\x50\xff\xff", encode_frame(0xAA, b"x")]),
    valid_frames.map(lambda f: encode_frame(f[0], f[1] + b"\xaa\xaa\xaa" + f[1])),  # a preamble inside
    valid_frames.map(lambda f: encode_frame(f[0], b"\xaa\xaa\xaa" + f[1])[:-2] + b"\xaa\xaa"),
)


@settings(max_examples=300, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(st.tuples(stream_parts, st.integers(1, 40)), max_size=8), st.data())
def test_tally_counts_what_feed_returns(parts, data) -> None:  # type: ignore[no-untyped-def]
    """`FrameParser.tally` (the proxy's counting path for frames it does not show) gives the same
    frames, checksum failures and garbage as `feed`, for any chunking and any mix of the two calls on
    one parser, and leaves the same state."""
    stream = b"".join(p * n for p, n in parts)
    cuts = sorted(data.draw(st.lists(st.integers(0, len(stream)), max_size=8)))
    chunks = [stream[a:b] for a, b in zip([0, *cuts], [*cuts, len(stream)], strict=True)]
    fed, tallied = FrameParser(), FrameParser()
    for chunk in chunks:
        events = fed.feed(chunk)
        want = _as_tally(events)
        if data.draw(st.booleans()):
            t = tallied.tally(chunk)
        else:
            t = Tally()
            t.add(tallied.feed(chunk))
        assert (dict(t.frames), t.bad, t.garbage, [repr(e) for e in t.problems]) == want
        assert t.first_bad == next((e for e in events if isinstance(e, ChecksumMismatch)), None)
        assert (tallied.pending(), tallied._fail_end, tallied._credit) == (fed.pending(), fed._fail_end, fed._credit)


def test_tally_of_a_flood_checks_each_distinct_frame_once(monkeypatch: pytest.MonkeyPatch) -> None:
    """1,024 identical bad frames and 1,024 valid ones: two CRCs (and one for the last, partial-or-not
    piece), not 2,048."""
    import pywsg.protocol.parser as parser_mod

    calls = []
    real = parser_mod.crc16
    monkeypatch.setattr(parser_mod, "crc16", lambda *a: calls.append(1) or real(*a))
    bad = Frame(0x50).encode()[:-2] + b"\0\0"
    t = FrameParser().tally(bad * 1024 + Frame(0x50).encode() * 1024)
    assert len(calls) <= 3
    assert (t.bad, dict(t.frames)) == (1024, {0x50: 1024})
    assert t.first_bad == next(e for e in FrameParser().feed(bad) if isinstance(e, ChecksumMismatch))


class _ScanOnly(FrameParser):
    """The parser without the split on the preamble: the reference the split must agree with."""

    _split_min = 1 << 62


@settings(max_examples=400, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(st.tuples(stream_parts, st.integers(1, 40)), max_size=8), st.data())
@example(parts=[(encode_frame(0x50, b""), 20), (encode_frame(0x50, b"")[:-2] + b"\0\0", 20)], data=None)
@example(parts=[(encode_frame(0x50, b""), 10), (encode_frame(0x50, b"")[:-2] + b"\0\xaa", 1)], data=None)
@example(parts=[(encode_frame(0x50, b""), 10), (encode_frame(0x50, b"")[:-2] + b"\0\0", 1), (b"\xaa", 1),
                (encode_frame(0x50, b""), 1)], data=None)
def test_split_feed_returns_exactly_what_the_scan_returns(parts, data) -> None:  # type: ignore[no-untyped-def]
    """000 §2.2 frames, read many at a time: `feed` splits a long read on the preamble (one lookup per
    frame) and must return the very events - frames, checksum failures, garbage, in order - and leave
    the very state the byte-by-byte scan does, for any stream, any chunking, with the device's CRC
    check switched between reads."""
    stream = b"".join(p * n for p, n in parts)
    if data is None:
        chunks, switches = [stream], [False]
    else:
        cuts = sorted(data.draw(st.lists(st.integers(0, len(stream)), max_size=6)))
        chunks = [stream[a:b] for a, b in zip([0, *cuts], [*cuts, len(stream)], strict=True)]
        switches = [data.draw(st.booleans()) for _ in chunks]
    split, scan = FrameParser(), _ScanOnly()
    for chunk, switch in zip(chunks, switches, strict=True):
        if switch:
            split.verify_checksum = scan.verify_checksum = not scan.verify_checksum
        assert split.feed(chunk) == scan.feed(chunk)
        assert (split.pending(), split._fail_end, split._credit, split.suppressed) == (
            scan.pending(), scan._fail_end, scan._credit, scan.suppressed)


def test_a_pipelined_read_checks_each_distinct_frame_once(monkeypatch: pytest.MonkeyPatch) -> None:
    """512 identical requests in one read (a client pipelining, or a flood) cost one CRC, not 512."""
    import pywsg.protocol.parser as parser_mod

    calls = []
    real = parser_mod.crc16
    monkeypatch.setattr(parser_mod, "crc16", lambda *a: calls.append(1) or real(*a))
    p = FrameParser()
    bad = Frame(0x50).encode()[:-2] + b"\0\0"
    events = p.feed(Frame(0x50).encode() * 256 + bad * 255 + Frame(0x40).encode())
    assert len(calls) <= 4
    assert frames_of(events) == [Frame(0x50)] * 256 + [Frame(0x40)]
    assert sum(isinstance(e, ChecksumMismatch) for e in events) == 255


_LOOP = encode_frame(0x06, b"\xaa\xaa\xaa\x01")  # a Loop request whose payload holds a preamble
_BAD = encode_frame(0x50, b"")[:-2] + b"\0\xaa"  # a failed frame ending in AAh


@pytest.mark.parametrize("chunks", [
    [b"\xaa", encode_frame(0x50, b"") * 20],  # a kept AAh, then a read of frames: 1 garbage byte
    [b"\xaa\xaa", encode_frame(0x50, b"") * 20],
    [encode_frame(0x50, b"") * 3 + _LOOP[:7], _LOOP[7:] + encode_frame(0x50, b"") * 20],
    [encode_frame(0x50, b"") * 10 + _BAD, encode_frame(0x50, b"") * 10],
    [_BAD * 10, b"\xaa\xaa" + encode_frame(0x50, b"") * 10],
    [encode_frame(0x50, b"")[:4], encode_frame(0x50, b"")[4:] + encode_frame(0x50, b"") * 20],
], ids=["aa", "aaaa", "preamble-in-payload-cut", "failed-ends-aa", "failed-then-aa", "header-cut"])
def test_split_feed_across_reads_returns_what_the_scan_returns(chunks: list[bytes]) -> None:
    """Reads cut frames anywhere (000 §2.2): what a read leaves buffered joins the next read's split."""
    split, scan = FrameParser(), _ScanOnly()
    for chunk in chunks:
        assert split.feed(chunk) == scan.feed(chunk)
        assert (split.pending(), split._fail_end, split._credit) == (scan.pending(), scan._fail_end, scan._credit)
