"""The unhappy path as the command manual states it (issue 12, device items 5–9), on the ManualClock.

Each test names the section of 000 (English command set) or 001 (German command set, firmware 4.0)
it checks; docs/fidelity.md records where the two are silent or disagree and what pywsg chose.
"""

from __future__ import annotations

import struct

import pytest

from pywsg.protocol import CATALOG, GripperState, Status, SystemFlag

from .devrig import Rig

S = Status
SF = SystemFlag
GS = GripperState
NAN = float("nan")


# ---------------------------------------------------------------- item 9: the catalog tells the truth

BAD_REQUESTS = [  # (command, payload, status pywsg answers): each must be in the command's catalog list
    (0x21, struct.pack("<Bff", 0, NAN, 50.0), S.E_INVALID_PARAMETER),
    (0x25, struct.pack("<ff", NAN, 50.0), S.E_INVALID_PARAMETER),
    (0x26, struct.pack("<ff", 50.0, float("inf")), S.E_INVALID_PARAMETER),
    (0x30, struct.pack("<f", NAN), S.E_INVALID_PARAMETER),
    (0x32, struct.pack("<f", NAN), S.E_INVALID_PARAMETER),
    (0x34, struct.pack("<ff", 60.0, 10.0), S.E_INVALID_PARAMETER),
    (0x37, b"\x02", S.E_INVALID_PARAMETER),
    *[(cid, struct.pack("<BH", 1, 5), S.E_INVALID_PARAMETER) for cid in (0x40, 0x41, 0x43, 0x44, 0x45)],
    (0x62, b"\x02", S.E_INVALID_PARAMETER),
    (0x72, b"\x07", S.E_INVALID_PARAMETER),
]


@pytest.mark.parametrize(("cid", "payload", "status"), BAD_REQUESTS)
def test_invalid_parameters_are_answered_with_a_listed_status(homed: Rig, cid: int, payload: bytes,
                                                              status: Status) -> None:
    """000 §1.3 / §3.x: the reply is one of the command's listed codes (the autouse fixture in
    conftest.py checks every reply of every device test against the catalog, docs/commands.md)."""
    assert homed.status(cid, payload) == status
    assert status in CATALOG[cid].statuses


@pytest.mark.parametrize("cid", [0x25, 0x26])
def test_grip_and_release_before_homing_are_not_initialized(rig: Rig, cid: int) -> None:
    """000 §3.2.2 note: "The gripper has to be referenced … to start a movement" — 25h/26h too."""
    assert rig.status(cid, width=30.0, speed=50.0) == S.E_NOT_INITIALIZED
    assert S.E_NOT_INITIALIZED in CATALOG[cid].statuses


def test_ack_refused_while_a_fault_persists_is_listed(homed: Rig) -> None:
    """App. B D16 SF_CURR_FAULT: "as soon as the engine has recovered … the Fast Stop can be committed"."""
    homed.g.faults.current_fault(True)
    assert homed.status(0x24, b"ack") == S.E_ACCESS_DENIED
    homed.g.faults.current_fault(False)
    assert homed.status(0x24, b"ack") == S.E_SUCCESS


def test_generated_reference_is_current() -> None:
    """docs/commands.md is generated from the catalog (also checked in tests/protocol)."""
    from pathlib import Path

    from pywsg.protocol.reference import markdown

    doc = Path(__file__).resolve().parents[2] / "docs" / "commands.md"
    assert doc.read_text() == markdown()
