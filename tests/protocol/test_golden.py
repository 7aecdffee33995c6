"""Every golden vector of the manual, through the public API: the example frames of 000 §1.2.1 and
§1.2.2 and the checksum of 000 Appendix D."""

from __future__ import annotations

import struct

import pytest

from pywsg.protocol import (
    CATALOG,
    Command,
    Frame,
    FrameParser,
    Status,
    crc16,
    crc16_bytewise,
    encode_frame,
)
from pywsg.protocol.crc import PREAMBLE_CRC

GOLDEN = [
    ("AA AA AA 01 00 00 E8 10", 0x01, b""),
    ("AA AA AA 01 02 00 12 34 6D 66", 0x01, b"\x12\x34"),
    ("AA AA AA 20 02 00 00 00 B3 FD", 0x20, b"\x00\x00"),
    ("AA AA AA 90 02 00 0E 00 FD 02", 0x90, b"\x0e\x00"),
    ("AA AA AA 30 06 00 00 00 00 00 16 43 DC CB", 0x30, b"\x00\x00\x00\x00\x16\x43"),
    ("AA AA AA 21 02 00 1A 00 67 CB", 0x21, b"\x1a\x00"),
    ("AA AA AA 21 02 00 00 00 28 04", 0x21, b"\x00\x00"),
]


@pytest.mark.parametrize(("hexframe", "cid", "payload"), GOLDEN)
def test_encode_matches_manual(hexframe: str, cid: int, payload: bytes) -> None:
    assert encode_frame(cid, payload) == bytes.fromhex(hexframe)
    assert Frame(cid, payload).encode() == bytes.fromhex(hexframe)


@pytest.mark.parametrize(("hexframe", "cid", "payload"), GOLDEN)
def test_crc_over_whole_frame_is_zero(hexframe: str, cid: int, payload: bytes) -> None:
    raw = bytes.fromhex(hexframe)
    assert crc16(raw) == 0
    assert crc16_bytewise(raw) == 0
    assert crc16(raw[:-2]) == struct.unpack("<H", raw[-2:])[0]


@pytest.mark.parametrize(("hexframe", "cid", "payload"), GOLDEN)
def test_parser_yields_manual_frames(hexframe: str, cid: int, payload: bytes) -> None:
    events = FrameParser().feed(bytes.fromhex(hexframe))
    assert events == [Frame(cid, payload)]


def test_example_2_checksum_is_666d() -> None:
    assert crc16(bytes.fromhex("AAAAAA0102001234")) == 0x666D


def test_preamble_crc() -> None:
    assert crc16(b"\xaa\xaa\xaa") == PREAMBLE_CRC
    assert crc16(bytes.fromhex("01000 0".replace(" ", "")), PREAMBLE_CRC) == 0x10E8


def test_reply_meanings() -> None:
    homing = Frame(0x20, b"\x00\x00")
    assert homing.status is Status.E_SUCCESS
    assert Frame(0x90, b"\x0e\x00").status is Status.E_CMD_UNKNOWN
    assert Frame(0x21, b"\x1a\x00").status is Status.E_CMD_PENDING
    assert Frame.reply(0x21, Status.E_CMD_PENDING).encode() == bytes.fromhex("AAAAAA2102001A0067CB")
    # the float example: 150.0 mm/s² (the manual calls it Get Acceleration; 31h's reply layout)
    status, values = CATALOG[Command.GET_ACCELERATION].decode_reply(b"\x00\x00\x00\x00\x16\x43")
    assert status is Status.E_SUCCESS and values == {"acceleration": 150.0}
