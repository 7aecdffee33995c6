"""Script plugins as the public cmd_measure.lua scripts behave (issue 12 items 10, 11).

The ROS driver's script (wsg_50_driver/cmd_measure.lua): measurements (busy, blocked, position) are
read first; B1h stops a busy motion and moves (``mc.move``); B2h sets speed mode and ``mc.speed``;
then "Stop if in speed mode": ``blocked and is_speed and pos <= 50 and def_speed < 0`` or
``blocked and is_speed and pos >= 50 and def_speed > 0`` → ``mc.stop(); is_speed = false``; the reply
reads state, position, speed and force *after* the command.
"""

from __future__ import annotations

import struct

import pytest

from pywsg.device import ManualClock, VirtualGripper
from pywsg.protocol import Frame, Status, SystemFlag

S = Status
SF_MOVING = int(SystemFlag.SF_MOVING)
SF_BLOCKED = int(SystemFlag.SF_BLOCKED_MINUS | SystemFlag.SF_BLOCKED_PLUS)


class TickingClock(ManualClock):
    """A ManualClock that moves on by 0.1 ms at every reading, as a real clock does between reads."""

    def __call__(self) -> float:
        self.now += 1e-4
        return self.now


def _gripper(clock: ManualClock, script: str = "ros_measure") -> tuple[VirtualGripper, object]:
    g = VirtualGripper("wsg50", clock=clock)
    s = g.open_session("tcp")
    g.handle_frame(s, Frame(0x20, b"\x01"))
    clock.advance(5)
    g.poll()
    g.load_plugin(script)
    return g, s


def _ros(g: VirtualGripper, s: object, cid: int, width: float = 0.0, speed: float = 0.0) -> tuple[int, ...]:
    reply = g.handle_frame(s, Frame(cid, struct.pack("<Bff", 0, width, speed)))[-1]  # type: ignore[arg-type]
    assert reply.status == S.E_SUCCESS
    return struct.unpack("<B5f", reply.params)  # type: ignore[return-value]


def test_position_replies_report_the_motion_they_started() -> None:
    """Item 10: one clock reading per request — the B1h reply's speed and SF_MOVING describe the motion
    the same request commanded, as 44h/40h read right after do (cmd_measure.lua reads them after mc.move)."""
    clock = TickingClock()
    g, s = _gripper(clock)
    moving_replies = 0
    for i in range(60):  # 30 Hz position control towards 20 mm
        state, _width, speed, *_ = _ros(g, s, 0xB1, width=110.0 - 3.0 * (i + 1), speed=60.0)
        after = g.speed()  # 44h a moment later (the clock ticked)
        if g.moving():
            moving_replies += 1
            assert state & SF_MOVING, i
            assert speed == pytest.approx(after, abs=0.5), i  # within 0.1 ms of acceleration
        clock.advance(1 / 30)
    assert moving_replies >= 55


def test_speed_reply_reports_the_speed() -> None:
    """Item 10 for B2h: the reply of a speed command during a motion carries its speed."""
    clock = TickingClock()
    g, s = _gripper(clock)
    _ros(g, s, 0xB2, speed=-30.0)
    clock.advance(0.5)
    state, _w, speed, *_ = _ros(g, s, 0xB2, speed=-30.0)
    assert state & SF_MOVING and speed == pytest.approx(-30.0, abs=0.1)


def test_speed_mode_closing_stops_only_when_blocked_at_or_below_50mm() -> None:
    """Item 11: ``blocked and is_speed and pos <= 50 and def_speed < 0`` → stop. Blocked at 70 mm while
    closing, the script keeps pushing (BLOCKED, motor force non-zero); blocked at 30 mm it stops."""
    clock = ManualClock()
    g, s = _gripper(clock)
    g.faults.block_at(70.0)
    _ros(g, s, 0xB2, speed=-40.0)
    clock.advance(2.0)
    g.poll()
    for _ in range(3):  # every request re-evaluates the rule: still pushing
        state, width, speed, force, *_ = _ros(g, s, 0xB0)
        assert width == pytest.approx(70.0) and speed == 0.0 and force > 0 and g.blocked()
        assert g.system_flags() & SF_BLOCKED and state & SF_BLOCKED
    g.faults.unblock()
    g.faults.block_at(30.0)
    clock.advance(2.0)
    g.poll()
    _ros(g, s, 0xB0)  # blocked at 30 mm now: this request's rule check stops the speed motion
    state, width, _speed, force, *_ = _ros(g, s, 0xB0)
    assert width == pytest.approx(30.0) and force == 0.0 and not state & SF_MOVING
    assert not g.blocked()


def test_speed_mode_opening_stops_only_when_blocked_at_or_above_50mm() -> None:
    """Item 11, opening: ``pos >= 50 and def_speed > 0``; blocked at 30 mm while opening: keeps pushing."""
    clock = ManualClock()
    g, s = _gripper(clock)
    _ros(g, s, 0xB1, width=10.0, speed=200.0)
    clock.advance(3.0)
    g.poll()
    g.faults.block_at(30.0, inside=True)
    _ros(g, s, 0xB2, speed=40.0)
    clock.advance(2.0)
    g.poll()
    _ros(g, s, 0xB0)
    _state, width, _speed, force, *_ = _ros(g, s, 0xB0)
    assert width == pytest.approx(30.0) and force > 0 and g.blocked()  # below 50 mm: keeps pushing
    g.faults.unblock()
    g.faults.block_at(80.0, inside=True)
    clock.advance(3.0)
    g.poll()
    _ros(g, s, 0xB0)
    _state, width, _speed, force, *_ = _ros(g, s, 0xB0)
    assert width == pytest.approx(80.0) and force == 0.0 and not g.blocked()


def test_position_command_does_not_leave_speed_mode() -> None:
    """Item 11: B1h does not reset ``is_speed`` — a later block at or below 50 mm while closing still
    stops the motion (the script's rule uses the last speed command's sign)."""
    clock = ManualClock()
    g, s = _gripper(clock)
    _ros(g, s, 0xB2, speed=-40.0)  # speed mode, closing
    clock.advance(0.2)
    _ros(g, s, 0xB1, width=10.0, speed=40.0)  # position command: speed mode stays on
    g.faults.block_at(30.0)
    clock.advance(5.0)
    g.poll()
    assert g.blocked()
    _ros(g, s, 0xB0)  # blocked, is_speed, pos <= 50, def_speed < 0: mc.stop()
    assert not g.blocked() and g.force() == 0.0
