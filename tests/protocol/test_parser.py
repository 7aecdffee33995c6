"""The incremental parser: chunking, resynchronisation, caps, checksum events, datagrams."""

from __future__ import annotations

from hypothesis import HealthCheck, given, settings
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
    seen += p.feed(b"\x00" * (MAX_PAYLOAD + 8))
    if request_max_payload(cid) >= len(payload):
        assert Frame(cid, payload) in frames_of(seen)


# -- hostile input (issue 13): same frames as the naive parser, errors once per span ------------


def naive_frames(stream: bytes, max_payload: int = MAX_PAYLOAD) -> list[Frame]:
    """Reference: try every candidate header with a full CRC (what the parser did before)."""
    from pywsg.protocol.crc import crc16

    out, pos = [], 0
    while True:
        start = stream.find(b"\xaa\xaa\xaa", pos)
        if start < 0:
            return out
        while start + 3 < len(stream) and stream[start + 3] == 0xAA:
            start += 1
        if len(stream) - start < 6:
            return out
        size = stream[start + 4] | stream[start + 5] << 8
        end = start + size + 8
        if size <= max_payload and end > len(stream):
            return out  # a header waits for its SIZE bytes (a frame inside it comes out later)
        if size > max_payload or crc16(stream[start:end]) != 0:
            pos = start + 1
            continue
        out.append(Frame(stream[start + 3], stream[start + 6 : end - 2]))
        pos = end


forged = st.builds(lambda i, n: b"\xaa\xaa\xaa" + bytes([i]) + n.to_bytes(2, "little"),
                   st.integers(0, 255), st.integers(0, 80))
pieces = st.one_of(st.binary(max_size=30), forged, valid_frames.map(lambda f: encode_frame(*f)))


@settings(max_examples=300, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(pieces, max_size=25), st.integers(1, 97))
def test_overlapping_candidates_find_exactly_the_naive_frames(parts, chunk) -> None:  # type: ignore[no-untyped-def]
    """Verifying overlapping candidates from running CRC states finds the frames a full CRC finds."""
    stream = b"".join(parts)
    p = FrameParser()
    got = frames_of(p.feed_all([stream[i : i + chunk] for i in range(0, len(stream), chunk)]))
    assert got == naive_frames(stream)


def test_forged_1kib_headers_get_one_checksum_error_per_span() -> None:
    stream = bytes.fromhex("AAAAAA990004") * 2000  # 12,000 bytes: ~2,000 candidates of 1 KiB
    events = FrameParser().feed(stream + HOMING_OK)
    errors = [e for e in events if isinstance(e, ChecksumMismatch)]
    assert 1 <= len(errors) <= len(stream) // 1032 + 1
    assert frames_of(events) == []  # HOMING_OK still lies inside the last forged span
    assert Frame(0x20, b"\x00\x00") in frames_of(FrameParser().feed(stream + b"\x00" * 1032 + HOMING_OK))


def test_oversized_headers_get_one_error_per_maximal_frame() -> None:
    stream = bytes.fromhex("AAAAAA99FFFF") * 1000
    events = FrameParser().feed(stream)
    assert 1 <= sum(isinstance(e, FrameTooLarge) for e in events) <= len(stream) // (MAX_PAYLOAD + 8) + 1


def test_bad_frames_that_do_not_overlap_each_get_their_error() -> None:
    bad = bytearray(encode_frame(0x21, b"\x01" * 9))
    bad[-1] ^= 0xFF
    events = FrameParser().feed(bytes(bad) * 50)
    assert sum(isinstance(e, ChecksumMismatch) for e in events) == 50


def test_datagram_is_one_frame_whatever_follows() -> None:
    """One frame per datagram: 40 frames in one datagram give one frame and trailing bytes."""
    events = parse_datagram(HOMING_OK * 40)
    assert events == [Frame(0x20, b"\x00\x00"), TrailingBytes(len(HOMING_OK) * 39)]
    forged_only = parse_datagram(bytes.fromhex("AAAAAA990004") * 10000)
    assert [type(e) for e in forged_only] == [ChecksumMismatch, TrailingBytes]
