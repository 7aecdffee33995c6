"""First smoke tests: homing, pre-position, grip, release on the injected clock."""

from __future__ import annotations

from pywsg.protocol import GripperState, Status, SystemFlag

from .devrig import Rig


def test_homing_references_and_answers_pending_then_success(rig: Rig) -> None:
    assert rig.status(0x21, flags=0, width=10.0, speed=50.0) == Status.E_NOT_INITIALIZED
    assert rig.width() == 0.0
    assert rig.status(0x20, direction=1) == Status.E_CMD_PENDING
    assert rig.flags() & SystemFlag.SF_MOVING
    out = rig.run(5)
    assert [(f.command_id, f.status) for f in out] == [(0x20, Status.E_SUCCESS)]
    assert rig.width() == 110.0
    assert rig.flags() & SystemFlag.SF_REFERENCED


def test_homing_at_the_end_stop_still_takes_the_stall_time(homed: Rig) -> None:
    """000 §3.2.1: homing drives into the end stop until it blocks; from the stop itself that is not
    instant (HOMING_STALL_S), so a fieldbus PLC polling the image sees the homing run (002 §4.4)."""
    from pywsg.device.handlers import HOMING_STALL_S

    r = homed
    assert r.width() == 110.0
    assert r.status(0x20, direction=1) == Status.E_CMD_PENDING
    assert r.flags() & SystemFlag.SF_MOVING
    assert r.run(HOMING_STALL_S * 0.9) == []
    out = r.run(HOMING_STALL_S * 0.2)
    assert [(f.command_id, f.status) for f in out] == [(0x20, Status.E_SUCCESS)]
    assert r.width() == 110.0 and r.flags() & SystemFlag.SF_REFERENCED


def test_grip_cycle_with_part(homed: Rig) -> None:
    r = homed
    r.g.faults.place_part(40.0)
    assert r.status(0x25, width=40.0, speed=100.0) == Status.E_CMD_PENDING
    assert r.gstate() == GripperState.GRIPPING
    out = r.run(5)
    assert [(f.command_id, f.status) for f in out] == [(0x25, Status.E_SUCCESS)]
    assert r.gstate() == GripperState.HOLDING
    assert r.status(0x26, width=100.0, speed=100.0) == Status.E_CMD_PENDING
    assert r.gstate() == GripperState.RELEASING
    out = r.run(5)
    assert [(f.command_id, f.status) for f in out] == [(0x26, Status.E_SUCCESS)]
    assert r.gstate() == GripperState.IDLE
    assert abs(r.width() - 100.0) < 1e-4
