"""jog() for the fieldbus JOG levels, snapshot(), the system log, and the real clock."""

from __future__ import annotations

import struct
import time

import pytest

from pywsg.device import LogEntry, VirtualGripper
from pywsg.protocol import Frame, GripperState, Status, SystemFlag

from .devrig import Rig

S = Status


def test_jog_requires_reference_and_no_fast_stop(rig: Rig) -> None:
    assert rig.g.jog(1, 10.0, 20.0) == S.E_NOT_INITIALIZED
    rig.home()
    rig.status(0x23)
    assert rig.g.jog(-1, 10.0, 20.0) == S.E_ACCESS_DENIED


def test_jog_moves_until_stopped(homed: Rig) -> None:
    homed.status(0x30, acceleration=150.0)
    assert homed.g.jog(-1, 20.0, 30.0) == S.E_SUCCESS
    assert homed.gstate() == GripperState.POSITIONING
    homed.clock.advance(2.0)
    snap = homed.g.snapshot()
    assert snap.moving and snap.speed == pytest.approx(-20.0)
    assert snap.width == pytest.approx(110.0 - 20.0 * 2.0 + 20.0 * 20.0 / (2 * 150.0), abs=1e-6)
    assert homed.status(0x21, flags=0, width=10.0, speed=10.0) == S.E_ALREADY_RUNNING
    assert homed.g.jog(0, 0.0, 0.0) == S.E_SUCCESS
    assert not homed.g.moving() and homed.gstate() == GripperState.IDLE


def test_jog_zero_speed_means_minimum_and_end_stop_blocks(homed: Rig) -> None:
    homed.status(0x21, flags=0, width=100.0, speed=100.0)
    homed.run(5)
    homed.g.jog(1, 0.0, 30.0)
    homed.clock.advance(1.0)
    assert homed.g.speed() == pytest.approx(5.0)
    homed.run(10)
    assert homed.g.width() == pytest.approx(110.0)
    assert homed.flags() & SystemFlag.SF_BLOCKED_PLUS and not homed.g.moving()


def test_jog_into_obstacle_presses_with_jog_force(homed: Rig) -> None:
    homed.g.faults.block_at(50.0)
    homed.g.jog(-1, 100.0, 30.0)
    homed.run(5)
    assert homed.g.width() == pytest.approx(50.0) and homed.g.force() == pytest.approx(30.0)
    assert homed.flags() & SystemFlag.SF_BLOCKED_MINUS


def test_jog_into_soft_limit_fast_stops(homed: Rig) -> None:
    homed.status(0x34, minus=60.0, plus=110.0)
    homed.g.jog(-1, 100.0, 30.0)
    homed.run(5)
    snap = homed.g.snapshot()
    assert snap.fast_stop and snap.width == pytest.approx(60.0, abs=1e-3)


def test_snapshot_and_log_listener(homed: Rig) -> None:
    seen: list[LogEntry] = []
    homed.g.log.add_listener(seen.append)
    homed.status(0x51, b"line 3")
    homed.status(0x23)
    snap = homed.g.snapshot()
    assert snap.tag == "line 3" and snap.fast_stop and snap.referenced and snap.model == "wsg50"
    assert snap.flags & SystemFlag.SF_FAST_STOP and snap.temperature == pytest.approx(30.0, abs=0.1)
    assert seen and "FAST STOP" in seen[-1].message and seen[-1].time == homed.clock.now


@pytest.mark.realtime
def test_real_clock_homing_completes() -> None:
    g = VirtualGripper("wsg50")  # time.monotonic
    s = g.open_session("web")
    assert g.handle_frame(s, Frame(0x30, struct.pack("<f", 5000.0)))[0].status == S.E_SUCCESS
    assert g.handle_frame(s, Frame(0x21, b"\x00" + bytes(8)))[0].status == S.E_NOT_INITIALIZED
    assert g.handle_frame(s, Frame(0x20, b"\x02"))[0].status == S.E_CMD_PENDING
    due = g.next_due()
    assert due is not None and due - time.monotonic() < 2.0
    while not g.referenced:
        nd = g.next_due()
        assert nd is not None
        time.sleep(max(0.0, nd - time.monotonic()))
        g.poll()
    assert g.snapshot().width == 0.0


def test_jog_speed_change_in_same_direction_takes_effect(homed: Rig) -> None:
    homed.g.jog(-1, 10.0, 20.0)
    homed.clock.advance(1.0)
    assert homed.g.speed() == pytest.approx(-10.0)
    homed.g.jog(-1, 30.0, 20.0)
    homed.clock.advance(1.0)
    assert homed.g.speed() == pytest.approx(-30.0)
    homed.g.jog(-1, 30.0, 20.0)  # same level again: the ramp is not restarted
    assert homed.g.speed() == pytest.approx(-30.0)


def test_reset_gripper_state_for_fieldbus_stop_ack(rig: Rig) -> None:
    """Fieldbus STOP/ACK: HOLDING (and NO_PART) back to IDLE, the hold force released."""
    rig.status(0x20, direction=1)
    rig.run(5)
    rig.g.faults.place_part(40.0)
    rig.status(0x25, width=40.0, speed=50.0)
    rig.run(5)
    snap = rig.g.snapshot()
    assert snap.gripper_state == GripperState.HOLDING and snap.force > 0
    held_at = snap.width
    rig.g.reset_gripper_state()
    snap = rig.g.snapshot()
    assert snap.gripper_state == GripperState.IDLE
    assert snap.force == 0.0 and abs(snap.width - held_at) < 1e-6
    rig.g.faults.remove_part()
    rig.status(0x25, width=40.0, speed=50.0)
    rig.run(5)
    assert rig.g.snapshot().gripper_state == GripperState.NO_PART
    rig.g.reset_gripper_state()
    assert rig.g.snapshot().gripper_state == GripperState.IDLE
