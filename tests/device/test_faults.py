"""Fault injection and the temperature model: flags, states and status codes as the manual says."""

from __future__ import annotations

import pytest

from pywsg.device.thermal import FAULT_C, WARNING_C
from pywsg.protocol import FingerFlag, GripperState, Status, SystemFlag

from .devrig import Rig

S = Status
SF = SystemFlag


def test_power_fault_fast_stops_and_blocks_ack_until_cleared(homed: Rig) -> None:
    homed.status(0x21, flags=0, width=10.0, speed=50.0)
    homed.clock.advance(0.2)
    homed.g.faults.power_fault(True)
    assert [f.status for f in homed.run(0.1)] == [S.E_CMD_ABORTED]
    f = homed.flags()
    assert f & SF.SF_POWER_FAULT and f & SF.SF_FAST_STOP
    assert homed.gstate() == GripperState.ERROR
    assert homed.status(0x24, b"ack") == S.E_ACCESS_DENIED
    homed.g.faults.power_fault(False)
    assert not homed.flags() & SF.SF_POWER_FAULT
    assert homed.status(0x24, b"ack") == S.E_SUCCESS
    assert homed.status(0x21, flags=0, width=10.0, speed=50.0) == S.E_CMD_PENDING


def test_current_fault(homed: Rig) -> None:
    homed.g.faults.current_fault(True)
    f = homed.flags()
    assert f & SF.SF_CURR_FAULT and f & SF.SF_FAST_STOP
    assert homed.status(0x24, b"ack") == S.E_ACCESS_DENIED
    homed.g.faults.current_fault(False)
    assert homed.status(0x24, b"ack") == S.E_SUCCESS
    assert not homed.flags() & (SF.SF_CURR_FAULT | SF.SF_FAST_STOP)


def test_finger_fault(rig: Rig) -> None:
    rig.g.faults.finger_fault(1, True)
    assert rig.flags() & SF.SF_FINGER_FAULT
    flags = rig.value(0x71)["flags"]
    assert flags & FingerFlag.POWER_FAULT and not flags & FingerFlag.POWER_ON
    assert rig.status(0x72, power=1) == S.E_CMD_FAILED  # over-current while enabling
    rig.g.faults.finger_fault(1, False)
    assert not rig.flags() & SF.SF_FINGER_FAULT
    assert rig.status(0x72, power=1) == S.E_CMD_PENDING


def test_block_and_part_validation(rig: Rig) -> None:
    with pytest.raises(ValueError, match="width"):
        rig.g.faults.place_part(-1.0)
    with pytest.raises(ValueError, match="stiffness"):
        rig.g.faults.place_part(10.0, stiffness=0)
    with pytest.raises(ValueError, match="finger"):
        rig.g.faults.finger_fault(2)


def test_block_moved_while_moving_replans_contact(homed: Rig) -> None:
    homed.status(0x21, flags=2, width=0.0, speed=50.0)
    homed.clock.advance(0.5)
    homed.g.faults.block_at(60.0)
    assert [f.status for f in homed.run(5)] == [S.E_AXIS_BLOCKED]
    assert abs(homed.width() - 60.0) < 1e-6
    homed.g.faults.unblock()
    assert not homed.flags() & SF.SF_BLOCKED_MINUS  # blocking condition resolved


def test_temperature_rises_with_force_and_overdrive_reaches_fault(homed: Rig) -> None:
    homed.status(0x37, flags=1)
    homed.status(0x32, force=120.0)
    homed.g.faults.place_part(40.0)
    homed.status(0x25, width=40.0, speed=100.0)
    homed.run(5)
    t0 = homed.g.temperature()
    due = homed.g.next_due()
    assert due is not None  # the warning threshold crossing is a due event
    homed.clock.set(due)
    homed.g.poll()
    assert homed.g.temperature() == pytest.approx(WARNING_C, abs=0.01)
    assert homed.flags() & SF.SF_TEMP_WARNING
    assert homed.g.temperature() > t0
    homed.run(3600)
    f = homed.flags()
    assert f & SF.SF_TEMP_FAULT
    assert homed.value(0x46)["temperature"] >= FAULT_C * 10
    assert homed.status(0x26, width=80.0, speed=50.0) == S.E_ACCESS_DENIED  # motion disabled
    # leaving overdrive reduces the force: the gripper cools below the critical level again
    homed.status(0x37, flags=0)
    homed.run(3600)
    f = homed.flags()
    assert not f & SF.SF_TEMP_FAULT
    assert homed.status(0x26, width=80.0, speed=50.0) == S.E_CMD_PENDING
    assert any("temperature fault" in m for m in homed.g.log.messages())


def test_heat_injection_disables_motion_and_aborts(homed: Rig) -> None:
    homed.status(0x21, flags=0, width=10.0, speed=20.0)
    homed.clock.advance(0.3)
    homed.g.faults.heat(45.0)
    assert [f.status for f in homed.run(0.01)] == [S.E_CMD_ABORTED]
    assert homed.flags() & SF.SF_TEMP_FAULT
    assert homed.status(0x21, flags=0, width=50.0, speed=20.0) == S.E_ACCESS_DENIED
    homed.run(1200)  # cools down: relaxes to equilibrium
    assert not homed.flags() & (SF.SF_TEMP_FAULT | SF.SF_TEMP_WARNING)
    assert homed.status(0x21, flags=0, width=50.0, speed=20.0) == S.E_CMD_PENDING
