"""``wsg decode`` as a user runs it: the real executable in a subprocess."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

WSG = [str(Path(sys.executable).with_name("wsg"))]


def run(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([*WSG, "decode", *args], capture_output=True, text=True, timeout=60)


def test_unknown_command_example() -> None:
    r = run("AA AA AA 90 02 00 0E 00 FD 02")
    assert r.returncode == 0, r.stderr
    assert "E_CMD_UNKNOWN" in r.stdout and "90h" in r.stdout and "checksum: OK" in r.stdout


def test_homing_pending_and_float_examples() -> None:
    r = run("AAh AAh AAh 20h 02h 00h 00h 00h B3h FDh", "0xAA 0xAA 0xAA 0x21 0x02 0x00 0x1A 0x00 0x67 0xCB",
            "AAAAAA3006000000000016 43DCCB")
    assert r.returncode == 0, r.stderr
    blocks = r.stdout.split("\n\n")
    assert "HOMING (20h)" in blocks[0] and "E_SUCCESS" in blocks[0]
    assert "PREPOSITION (21h)" in blocks[1] and "E_CMD_PENDING" in blocks[1]
    assert "acceleration: 150 mm/s²" in blocks[2]


def test_wrong_crc_prints_expected() -> None:
    r = run("AA AA AA 20 02 00 00 00 B3 FE")
    assert r.returncode == 1
    assert "WRONG" in r.stdout and "expected FDB3h" in r.stdout and "received FEB3h" in r.stdout
    assert "Traceback" not in r.stderr


def test_truncated_frame_is_reported() -> None:
    r = run("AA AA AA 21 09 00 00 00")
    assert r.returncode == 1
    assert "truncated" in r.stdout and "Traceback" not in r.stderr


def test_not_hex_is_a_usage_error() -> None:
    r = run("AA ZZ")
    assert r.returncode == 2 and "not a hex byte" in r.stderr


def test_json_output() -> None:
    r = run("--json", "AA AA AA 21 02 00 1A 00 67 CB AA AA AA 43 03 00 01 0A 00 00 00")
    out = json.loads(r.stdout)
    assert out[0]["status"] == "E_CMD_PENDING" and out[0]["checksum_ok"] is True
    assert out[1]["command"] == "GET_OPENING_WIDTH"
    assert out[1]["checksum_ok"] is False and out[1]["checksum_expected"] is not None


def test_request_parameters_with_units() -> None:
    from pywsg.protocol import CATALOG, encode_frame

    raw = encode_frame(0x21, CATALOG[0x21].encode_request(flags=1, width=42.5, speed=80.0))
    r = run(raw.hex())
    assert r.returncode == 0
    assert "request PREPOSITION" in r.stdout
    assert "width: 42.5 mm" in r.stdout and "speed: 80 mm/s" in r.stdout and "RELATIVE" in r.stdout
