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


# ---------------------------------------------------------------- item 5: FAST STOP turns the drive off

def _hold(r: Rig, width: float = 40.0) -> None:
    r.g.faults.place_part(width)
    assert r.status(0x25, width=width, speed=100.0) == S.E_CMD_PENDING
    assert [f.status for f in r.run(5)] == [S.E_SUCCESS]
    assert r.gstate() == GS.HOLDING and r.value(0x45, flags=0, period_ms=0)["force"] == pytest.approx(80.0)


def test_fast_stop_while_holding_releases_the_force_and_sets_error(homed: Rig) -> None:
    """002 §3.1 bit 5 / App. B D12: FAST STOP "Stop and turn off the motor" — no gripping force; 001 §3.4.2
    (41h Error): "… oder ein Fast Stop wurde ausgelöst. Dieser Zustand bleibt erhalten, bis der nächste
    Bewegungsbefehl empfangen wird. Sofern der FAST STOP-Zustand aktiv ist, muss dieser zunächst quittiert
    werden." """
    _hold(homed)
    assert homed.status(0x23) == S.E_SUCCESS
    assert homed.value(0x45, flags=0, period_ms=0)["force"] == 0.0
    assert homed.gstate() == GS.ERROR
    assert homed.width() == pytest.approx(40.0, abs=1e-6)  # the fingers rest on the part, unsqueezed
    assert homed.flags() & SF.SF_FAST_STOP and not homed.flags() & SF.SF_MOVING
    homed.clock.advance(10.0)
    assert homed.g.force() == 0.0 and homed.run(1.0) == []  # nothing comes back on by itself
    # acknowledged: still ERROR until the next motion command, which is accepted again
    assert homed.status(0x24, b"ack") == S.E_SUCCESS
    assert homed.gstate() == GS.ERROR
    assert homed.status(0x26, width=80.0, speed=100.0) == S.E_CMD_PENDING
    assert homed.gstate() == GS.RELEASING
    assert [f.status for f in homed.run(5)] == [S.E_SUCCESS]
    assert homed.gstate() == GS.IDLE


def test_fast_stop_at_rest_sets_error_too(homed: Rig) -> None:
    """001 §3.4.2: Error (7) "… oder ein Fast Stop wurde ausgelöst" — not only when a motion ran."""
    assert homed.gstate() == GS.IDLE
    assert homed.status(0x23) == S.E_SUCCESS
    assert homed.gstate() == GS.ERROR
    assert homed.status(0x24, b"ack") == S.E_SUCCESS
    assert homed.status(0x21, flags=0, width=30.0, speed=100.0) == S.E_CMD_PENDING
    assert homed.gstate() == GS.POSITIONING
    homed.run(5)
    assert homed.gstate() == GS.IDLE


def test_part_can_be_gripped_again_after_fast_stop(homed: Rig) -> None:
    """000 §3.2.6: after the acknowledge a grip of the part the fingers rest on holds it again."""
    _hold(homed)
    homed.status(0x23)
    homed.status(0x24, b"ack")
    assert homed.status(0x25, width=40.0, speed=100.0) == S.E_CMD_PENDING
    assert [f.status for f in homed.run(5)] == [S.E_SUCCESS]
    assert homed.gstate() == GS.HOLDING and homed.g.force() == pytest.approx(80.0)


@pytest.mark.parametrize("cause", ["power", "current", "disconnect"])
def test_every_fast_stop_cause_turns_the_drive_off(homed: Rig, cause: str) -> None:
    """App. B D16/D17 (current / power fault raise FAST STOP), 000 §2.x (unannounced TCP close): the same
    FAST STOP, so the same drive-off and ERROR."""
    _hold(homed)
    if cause == "power":
        homed.g.faults.power_fault(True)
    elif cause == "current":
        homed.g.faults.current_fault(True)
    else:
        homed.g.close_session(homed.s)
        homed.s = homed.g.open_session("tcp", peer="127.0.0.1:5556")
    assert homed.g.force() == 0.0 and homed.g.gstate == GS.ERROR and homed.g.fast_stopped


# ---------------------------------------------------------------- item 6: homing into an obstacle

def test_homing_into_an_obstacle_sets_a_wrong_reference_with_a_warning(rig: Rig) -> None:
    """000 §3.2.1: "The blocking position is used as new origin … Obstacles in the movement range of the
    fingers and collision with these during homing may result in a wrong reference point"."""
    rig.g.faults.block_at(30.0)  # below the fingers (at 55 mm): in the way of a negative homing
    assert rig.status(0x20, direction=2) == S.E_CMD_PENDING
    assert [f.status for f in rig.run(5)] == [S.E_SUCCESS]  # the firmware cannot tell it from the end stop
    assert rig.flags() & SF.SF_REFERENCED
    assert rig.width() == pytest.approx(0.0, abs=1e-6)  # reports 0 mm ...
    assert rig.g.true_width() == pytest.approx(30.0, abs=1e-6)  # ... at 30 mm
    warnings = [e for e in rig.g.log.entries if e.level == "warning"]
    assert warnings and "wrong reference point" in warnings[-1].message
    # every later width is off by the same 30 mm
    rig.status(0x21, flags=0, width=50.0, speed=100.0)
    assert [f.status for f in rig.run(5)] == [S.E_SUCCESS]
    assert rig.width() == pytest.approx(50.0) and rig.g.true_width() == pytest.approx(80.0)
    # the real end stop is now at 80 mm on the reported scale: a move to 100 mm runs into it
    rig.status(0x21, flags=0, width=100.0, speed=100.0)
    assert [f.status for f in rig.run(5)] == [S.E_RANGE_ERROR]  # 000 §3.2.2: "a … hard limit was reached"
    assert rig.width() == pytest.approx(80.0) and rig.g.true_width() == pytest.approx(110.0)
    # homing again without the obstacle puts the reference right
    rig.g.faults.unblock()
    rig.status(0x20, direction=2)
    assert [f.status for f in rig.run(5)] == [S.E_SUCCESS]
    assert rig.width() == pytest.approx(0.0, abs=1e-6) and rig.g.true_width() == pytest.approx(0.0, abs=1e-6)


def test_homing_positive_into_an_obstacle(rig: Rig) -> None:
    """000 §3.2.1, homing in positive direction: the obstacle's position becomes the full stroke."""
    rig.g.faults.block_at(80.0)
    rig.status(0x20, direction=1)
    assert [f.status for f in rig.run(5)] == [S.E_SUCCESS]
    assert rig.width() == pytest.approx(110.0) and rig.g.true_width() == pytest.approx(80.0)


# ---------------------------------------------------------------- item 8: E_TIMEOUT

def _release_into_block(homed: Rig) -> float:
    homed.status(0x21, flags=0, width=20.0, speed=200.0)
    homed.run(5)
    homed.g.faults.block_at(60.0)  # above the fingers: in the way of opening
    start = homed.clock.now
    assert homed.status(0x26, width=100.0, speed=100.0) == S.E_CMD_PENDING
    return start


def test_release_blocked_by_an_obstacle_ends_with_timeout(homed: Rig) -> None:
    """000 §3.2.7 lists E_TIMEOUT ("Timeout while releasing"), not E_AXIS_BLOCKED, as a final status of
    26h: the drive pushes on and the command ends E_TIMEOUT MOTION_TIMEOUT_S (1 s) after the release's
    planned end; 41h then says ERROR (000 §3.4.2)."""
    from pywsg.device.axis import MOTION_TIMEOUT_S
    from pywsg.device.motion import plan_move

    start = _release_into_block(homed)
    planned = plan_move(start, 20.0, 100.0, 100.0, homed.g.acceleration).end_time
    deadline = planned + MOTION_TIMEOUT_S
    assert homed.run(deadline - start - 1e-3) == []  # pushing: no final reply yet
    assert homed.gstate() == GS.RELEASING and homed.flags() & SF.SF_BLOCKED_PLUS
    assert homed.width() == pytest.approx(60.0) and homed.g.force() > 0
    assert [(f.command_id, f.status) for f in homed.run(0.01)] == [(0x26, S.E_TIMEOUT)]
    assert homed.gstate() == GS.ERROR and homed.g.force() == 0.0
    assert homed.flags() & SF.SF_CMD_FAILURE


def test_blocked_release_completes_when_the_obstacle_goes(homed: Rig) -> None:
    """000 §3.2.7: the release reaches its width (E_SUCCESS) if the obstacle goes before the timeout."""
    _release_into_block(homed)
    homed.run(0.6)
    homed.g.faults.unblock()
    assert [f.status for f in homed.run(5)] == [S.E_SUCCESS]
    assert homed.width() == pytest.approx(100.0) and homed.gstate() == GS.IDLE


# ---------------------------------------------------------------- a failed motion: 41h ERROR

def test_blocked_preposition_leaves_error_until_the_next_motion(homed: Rig) -> None:
    """000 §3.4.2 Error (7): "An error occurred during the gripping process. This state will persist until
    the next Grip Part, Release Part or Pre-position Fingers command is issued" — a 21h that ends
    E_AXIS_BLOCKED is such an error (002 §4.1 / 003 §5.1 say the same for the fieldbus MOVE)."""
    homed.g.faults.block_at(60.0)
    homed.status(0x21, flags=2, width=20.0, speed=100.0)
    assert [f.status for f in homed.run(5)] == [S.E_AXIS_BLOCKED]
    assert homed.gstate() == GS.ERROR
    homed.g.faults.unblock()
    homed.status(0x21, flags=2, width=20.0, speed=100.0)
    assert [f.status for f in homed.run(5)] == [S.E_SUCCESS]
    assert homed.gstate() == GS.IDLE


def test_stop_is_no_error(homed: Rig) -> None:
    """000 §3.2.3: Stop (22h) ends a motion with E_CMD_ABORTED by request: 41h goes back to IDLE."""
    homed.status(0x21, flags=0, width=10.0, speed=50.0)
    homed.clock.advance(0.2)
    assert [f.status for f in homed.send(0x22)] == [S.E_CMD_ABORTED, S.E_SUCCESS]
    assert homed.gstate() == GS.IDLE
