"""No read changes what the gripper reports (issue 24 item 4), in raw frames on the manual clock.

App. B D18 SF_CMD_FAILURE: "The last command returned an error." A read that finds nothing to read —
52h without a tag (000 §3.5.3 E_NOT_AVAILABLE), 35h without soft limits (§3.3.6), 63h/73h of a generic
finger (§3.6.4) — is not a failed command of the gripper's: it neither sets nor clears the flag, and no
other read changes the flags, the gripper state or anything else a client can read back.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import pytest

from pywsg.device.gripper import QUERY_IDS
from pywsg.protocol import Frame, Status, SystemFlag

from .devrig import Rig, make_rig

S = Status

# every read of the command set (000 chapter 3), with a well-formed payload; 40h–45h without auto-update
READS: dict[int, bytes] = {
    0x06: b"\x01\x02", 0x31: b"", 0x33: b"", 0x35: b"", 0x40: b"\x00\x00\x00", 0x41: b"\x00\x00\x00",
    0x42: b"\x00", 0x43: b"\x00\x00\x00", 0x44: b"\x00\x00\x00", 0x45: b"\x00\x00\x00", 0x46: b"",
    0x50: b"", 0x52: b"", 0x53: b"", 0x60: b"", 0x61: b"", 0x63: b"", 0x70: b"", 0x71: b"", 0x73: b"",
}


def _state(rig: Rig) -> dict[str, Any]:
    snap = dataclasses.asdict(rig.g.snapshot())
    for moving_on in ("time", "temperature"):
        snap.pop(moving_on)
    snap["fingers"] = [int(f.flags()) for f in rig.g.fingers]
    return snap


def test_every_read_is_listed() -> None:
    assert set(READS) == set(QUERY_IDS)


@pytest.mark.parametrize("homed_first", [False, True], ids=["fresh", "homed"])
def test_no_read_changes_the_device(homed_first: bool) -> None:
    """A fresh gripper (no tag, no soft limits, generic fingers) and a homed one: every read, in raw
    frames, leaves the device as it was; SF_CMD_FAILURE stays off although 35h, 52h, 63h, 73h answer
    E_NOT_AVAILABLE."""
    rig = make_rig()
    if homed_first:
        rig.home()
    before = _state(rig)
    assert not before["flags"] & SystemFlag.SF_CMD_FAILURE
    answered = {}
    for cid, payload in READS.items():
        (reply,) = rig.g.feed(rig.s, Frame(cid, payload).encode())
        answered[cid] = reply.status
    assert {cid for cid, st in answered.items() if st != S.E_SUCCESS} == {0x35, 0x52, 0x63, 0x73}
    assert _state(rig) == before


def test_reads_do_not_clear_a_failure_either() -> None:
    """App. B D18 after a failed command (21h before homing: E_NOT_INITIALIZED): the flag stays through
    every read, so a client can read it; the next successful command clears it."""
    rig = make_rig()
    assert rig.status(0x21, flags=0, width=10.0, speed=10.0) == S.E_NOT_INITIALIZED
    for cid, payload in READS.items():
        rig.g.feed(rig.s, Frame(cid, payload).encode())
        assert rig.g.system_flags() & SystemFlag.SF_CMD_FAILURE, f"{cid:02X}h cleared it"
    assert rig.status(0x30, acceleration=1000.0) == S.E_SUCCESS
    assert not rig.g.system_flags() & SystemFlag.SF_CMD_FAILURE


def test_a_malformed_read_is_still_a_failed_command() -> None:
    """A read with the wrong length is a bad request (E_NO_PARAM_EXPECTED, 000 §3.3.2): that sets D18."""
    rig = make_rig()
    assert rig.status(0x31, b"\x00") == S.E_NO_PARAM_EXPECTED
    assert rig.g.system_flags() & SystemFlag.SF_CMD_FAILURE
