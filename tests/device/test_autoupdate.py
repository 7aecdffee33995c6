"""Auto-update subscriptions (40h, 41h, 43h, 44h, 45h): period, change-only, per session."""

from __future__ import annotations

import itertools
import struct

from pywsg.protocol import Frame, GripperState, Status

from .devrig import Rig


def test_always_mode_sends_every_period(homed: Rig) -> None:
    first = homed.call(0x43, flags=1, period_ms=100)
    assert first.status == Status.E_SUCCESS and struct.unpack("<f", first.params)[0] == 110.0
    out = homed.run(1.0)
    assert len(out) == 10 and all(f.command_id == 0x43 and f.status == Status.E_SUCCESS for f in out)
    assert homed.g.next_due() == homed.clock.now + 0.1 or abs(homed.g.next_due() - homed.clock.now - 0.1) < 1e-9


def test_stopped_by_flags_clear(homed: Rig) -> None:
    homed.call(0x41, flags=1, period_ms=10)
    assert len(homed.run(0.1)) == 10
    homed.call(0x41, flags=0, period_ms=0)
    assert homed.run(1.0) == []
    assert homed.g.next_due() is None


def test_change_only_sleeps_while_nothing_changes(homed: Rig) -> None:
    homed.call(0x43, flags=3, period_ms=20)
    assert homed.g.next_due() is None or homed.run(1.0) == []
    homed.status(0x21, flags=0, width=10.0, speed=100.0)
    out = homed.run(3.0)
    widths = [struct.unpack("<f", f.params)[0] for f in out if f.command_id == 0x43]
    finals = [f for f in out if f.command_id == 0x21]
    assert finals and finals[0].status == Status.E_SUCCESS
    assert len(widths) > 20
    assert all(abs(b - a) >= 0.01 for a, b in itertools.pairwise(widths))
    assert widths == sorted(widths, reverse=True) and abs(widths[-1] - 10.0) < 0.01  # last step below the threshold
    assert homed.run(2.0) == []  # at rest again: nothing more


def test_change_only_keeps_the_period(homed: Rig) -> None:
    homed.call(0x43, flags=3, period_ms=200)
    homed.status(0x30, acceleration=150.0)  # a slow ramp: the width changes for longer than 3 periods
    homed.status(0x21, flags=0, width=10.0, speed=400.0)
    times: list[float] = []

    def deliver(f: Frame) -> None:
        if f.command_id == 0x43:
            times.append(homed.clock.now)

    homed.s.deliver = deliver
    homed.run(2.0)
    assert len(times) >= 3
    assert all(b - a >= 0.2 - 1e-9 for a, b in itertools.pairwise(times))


def test_gripper_state_change_only(homed: Rig) -> None:
    homed.call(0x41, flags=3, period_ms=10)
    homed.g.faults.place_part(50.0)
    homed.status(0x25, width=50.0, speed=100.0)
    out = homed.run(3.0)
    states = [f.params[0] for f in out if f.command_id == 0x41]
    assert states == [GripperState.GRIPPING, GripperState.HOLDING]


def test_system_state_change_only_sees_moving_flag(homed: Rig) -> None:
    homed.call(0x40, flags=3, period_ms=10)
    homed.status(0x21, flags=0, width=100.0, speed=100.0)
    out = homed.run(2.0)
    flags = [struct.unpack("<I", f.params)[0] for f in out if f.command_id == 0x40]
    assert len(flags) == 2 and flags[0] & 2 and not flags[1] & 2


def test_subscriptions_are_per_session(homed: Rig) -> None:
    other = homed.g.open_session("web")
    homed.g.handle_frame(other, Frame(0x44, b"\x01\x64\x00"))
    assert homed.run(1.0) == []  # rig's session gets nothing
    homed.clock.advance(0.05)
    got = [s for s, _ in homed.g.poll()]
    assert got == [] or all(s is other for s in got)
    homed.g.close_session(other)
    homed.clock.advance(1)
    assert homed.g.poll() == []


def test_force_auto_update(homed: Rig) -> None:
    homed.call(0x45, flags=3, period_ms=10)
    homed.g.faults.place_part(50.0)
    homed.status(0x25, width=50.0, speed=100.0)
    out = homed.run(3.0)
    forces = [struct.unpack("<f", f.params)[0] for f in out if f.command_id == 0x45]
    assert forces == [80.0]
