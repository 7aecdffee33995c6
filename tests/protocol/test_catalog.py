"""The command catalog: completeness, typed encode/decode, round trips through the parser."""

from __future__ import annotations

import math
import struct

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pywsg.protocol import CATALOG, Command, Field, Frame, FrameParser, Kind, Status, encode_frame
from pywsg.protocol.catalog import CommandSpec

MANUAL_IDS = {0x06, 0x07, *range(0x20, 0x27), *range(0x30, 0x39), *range(0x40, 0x47), *range(0x50, 0x54),
              *range(0x60, 0x64), *range(0x70, 0x74)}


def test_every_manual_command_is_in_the_catalog() -> None:
    assert set(CATALOG) == MANUAL_IDS
    assert {c.value for c in Command} == MANUAL_IDS


def test_kinds() -> None:
    pending = {cid for cid, s in CATALOG.items() if s.kind is Kind.PENDING}
    assert pending == {0x20, 0x21, 0x25, 0x26}
    assert {cid for cid, s in CATALOG.items() if s.auto_update} == {0x40, 0x41, 0x43, 0x44, 0x45}
    assert CATALOG[0x62].kind is Kind.PENDING_WHEN_ON


def test_preposition_layout_matches_manual() -> None:
    spec = CATALOG[Command.PREPOSITION]
    payload = spec.encode_request(flags=2, width=50.0, speed=100.0)
    assert payload == b"\x02" + struct.pack("<ff", 50.0, 100.0)
    assert spec.decode_request(payload) == {"flags": 2, "width": 50.0, "speed": 100.0}


def test_system_limits_reply_has_eight_floats() -> None:
    spec = CATALOG[Command.GET_SYSTEM_LIMITS]
    assert spec.reply_layout.fixed_size == 32
    assert [f.unit for f in spec.reply][:3] == ["mm", "mm/s", "mm/s"]


def test_error_replies_carry_only_the_status() -> None:
    spec = CATALOG[Command.GET_SOFT_LIMITS]
    assert spec.encode_reply(Status.E_NOT_AVAILABLE) == b"\x01\x00"
    assert spec.decode_reply(b"\x01\x00") == (Status.E_NOT_AVAILABLE, {})


def test_wrong_length_is_a_value_error() -> None:
    with pytest.raises(ValueError, match="expected 9 bytes"):
        CATALOG[Command.PREPOSITION].decode_request(b"\x00" * 8)


def test_missing_and_mistyped_parameters() -> None:
    with pytest.raises(ValueError, match="missing parameter 'speed'"):
        CATALOG[Command.GRIP_PART].encode_request(width=1.0)
    with pytest.raises(TypeError):
        CATALOG[Command.GRIP_PART].encode_request(width="wide", speed=1.0)
    with pytest.raises(ValueError, match="out of range"):
        CATALOG[Command.HOMING].encode_request(direction=256)


def _value(f: Field) -> st.SearchStrategy[object]:
    if f.type == "f32":
        return st.floats(width=32, allow_nan=False)
    if f.type == "u8":
        return st.integers(0, 0xFF)
    if f.type == "u16":
        return st.integers(0, 0xFFFF)
    if f.type == "u32":
        return st.integers(0, 0xFFFFFFFF)
    if f.type == "i16":
        return st.integers(-0x8000, 0x7FFF)
    if f.type == "str":
        return st.text(alphabet=st.characters(min_codepoint=32, max_codepoint=126), max_size=f.max_len or 64)
    return st.binary(max_size=f.max_len or 64)


def _values_for(fields: tuple[Field, ...]) -> st.SearchStrategy[dict[str, object]]:
    return st.fixed_dictionaries({f.name: _value(f) for f in fields})


def _same(a: object, b: object) -> bool:
    if isinstance(a, float) and isinstance(b, float):
        return a == b or (math.isnan(a) and math.isnan(b))
    return int(a) == int(b) if isinstance(a, int) and isinstance(b, int) else a == b


@settings(max_examples=400)
@given(st.sampled_from(sorted(CATALOG)), st.data(), st.integers(1, 20))
def test_request_and_reply_round_trip_through_the_parser(cid: int, data: st.DataObject, chunk: int) -> None:
    spec: CommandSpec = CATALOG[cid]
    req = data.draw(_values_for(spec.request))
    rep = data.draw(_values_for(spec.reply))
    stream = encode_frame(cid, spec.encode_request(req)) + encode_frame(cid, spec.encode_reply(Status.E_SUCCESS, rep))
    p = FrameParser()
    events = p.feed_all(stream[i : i + chunk] for i in range(0, len(stream), chunk))
    assert len(events) == 2 and all(isinstance(e, Frame) for e in events)
    got_req = spec.decode_request(events[0].payload)  # type: ignore[union-attr]
    status, got_rep = spec.decode_reply(events[1].payload)  # type: ignore[union-attr]
    assert status is Status.E_SUCCESS
    assert all(_same(req[k], got_req[k]) for k in req)
    assert all(_same(rep[k], got_rep[k]) for k in rep)


def test_generated_command_reference_is_current() -> None:
    from pathlib import Path

    from pywsg.protocol.reference import markdown

    doc = Path(__file__).resolve().parents[2] / "docs" / "commands.md"
    assert doc.read_text(encoding="utf-8") == markdown(), "regenerate: python -m pywsg.protocol.reference"
