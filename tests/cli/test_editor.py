"""The Custom Command Editor syntax (command manual, chapter 2): byte-exact packets."""

from __future__ import annotations

import struct

import pytest

from pywsg.protocol.editor import PayloadSyntaxError, build_packet, parse_command_id, parse_payload, tokenize

from .conftest import run_wsg

# The manual's examples (1.2.1, 1.2.2 and chapter 2), as `wsg send` arguments -> wire bytes.
MANUAL = [
    (["1"], "AA AA AA 01 00 00 E8 10"),
    (["1", "0x12", "0x34"], "AA AA AA 01 02 00 12 34 6D 66"),
    (["1", "18", "52"], "AA AA AA 01 02 00 12 34 6D 66"),  # same bytes, decimal
    (["0x20", "0", "0"], "AA AA AA 20 02 00 00 00 B3 FD"),
    (["0x90", "0x0E", "0"], "AA AA AA 90 02 00 0E 00 FD 02"),
    (["30h", "0", "0", "150.0f"], "AA AA AA 30 06 00 00 00 00 00 16 43 DC CB"),
    (["0x21", "0x1A", "0x00"], "AA AA AA 21 02 00 1A 00 67 CB"),
    (["0x21", "0,0"], "AA AA AA 21 02 00 00 00 28 04"),
]


def test_manual_examples_in_process() -> None:
    for args, wire in MANUAL:
        assert build_packet(args[0], args[1:]).wire == bytes.fromhex(wire), args


@pytest.mark.parametrize(("args", "wire"), MANUAL[:2] + MANUAL[5:6])
def test_send_dry_run_prints_the_exact_packet(args: list[str], wire: str) -> None:
    r = run_wsg("send", "--dry-run", *args)
    assert r.code == 0, r
    tx = r.out.splitlines()[0]
    assert tx.startswith("TX  " + wire + "  "), r


def test_send_dry_run_json_float_text_and_name() -> None:
    r = run_wsg("send", "--dry-run", "--json", "ack-fast-stop", '"ack"')
    assert r.code == 0, r
    packet = r.json()["packet"]
    assert packet["hex"] == "AA AA AA 24 03 00 61 63 6B DC B9"
    assert packet["params"] == {"key": "ack"}
    r = run_wsg("send", "--dry-run", "--json", "preposition", "0x02", "50.0f", "-12.5f")
    packet = r.json()["packet"]
    payload = bytes.fromhex(packet["hex"])[6:-2]
    assert payload == b"\x02" + struct.pack("<ff", 50.0, -12.5)
    assert packet["command"] == "PREPOSITION" and packet["params"]["width"] == 50.0


def test_bad_payload_is_a_usage_error_naming_the_item() -> None:
    r = run_wsg("send", "--dry-run", "0x24", "ack")
    assert r.code == 2
    assert "'ack'" in r.err and '"ack"' in r.err
    r = run_wsg("send", "--dry-run", "1", "300")
    assert r.code == 2 and "300u16" in r.err
    r = run_wsg("send", "--dry-run", "--json", "nosuchcommand")
    assert r.code == 2 and "unknown command" in r.json()["error"]


def test_item_forms() -> None:
    assert parse_payload("0x20 32 -1 0xff") == b"\x20\x20\xff\xff"
    assert parse_payload("150.0f") == struct.pack("<f", 150.0)
    assert parse_payload("150f 1e2F .5f") == struct.pack("<fff", 150.0, 100.0, 0.5)
    assert parse_payload('"ack"') == b"ack"
    assert parse_payload('"a b,c"') == b"a b,c"
    assert parse_payload(r'"q\"\\\x41"') == b'q"\\A'
    assert parse_payload("1000u16 -2i16 7u32") == struct.pack("<HhI", 1000, -2, 7)
    assert parse_payload(["1", '"x"', "2"]) == b"\x01x\x02"
    assert parse_payload("") == b""
    assert tokenize('1,2 "a, b"3') == ["1", "2", '"a, b"', "3"]


@pytest.mark.parametrize("bad", ["256", "-129", "0x100", "-0x1", "1.5", '"open', "abc", "70000u16", "1e39f",
                                 '"\u20ac"', r'"\q"'])
def test_item_errors(bad: str) -> None:
    with pytest.raises(PayloadSyntaxError):
        parse_payload(bad)


def test_command_ids() -> None:
    assert parse_command_id("33") == parse_command_id("0x21") == parse_command_id("21h") == 0x21
    assert parse_command_id("preposition") == parse_command_id("PREPOSITION") == 0x21
    assert parse_command_id("get-system-state") == 0x40
    for bad in ("256", "0x1FF", "nope"):
        with pytest.raises(PayloadSyntaxError):
            parse_command_id(bad)
