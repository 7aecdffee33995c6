"""Motion correctness: width(t) follows the trapezoidal profile; speed limits; 43h/44h consistent."""

from __future__ import annotations

import math
import struct

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pywsg.device.motion import plan_move, plan_stop, plan_velocity

from .devrig import Rig


def trapezoid(t: float, x0: float, x1: float, v: float, a: float) -> tuple[float, float]:
    """Reference profile written independently of the device code: (width, velocity) at t."""
    d = abs(x1 - x0)
    s = 1.0 if x1 >= x0 else -1.0
    if d <= v * v / a:
        tp = math.sqrt(d / a)
        if t <= 0:
            return x0, 0.0
        if t <= tp:
            return x0 + s * a * t * t / 2, s * a * t
        if t <= 2 * tp:
            u = 2 * tp - t
            return x1 - s * a * u * u / 2, s * a * u
        return x1, 0.0
    ta = v / a
    tc = (d - v * ta) / v
    if t <= 0:
        return x0, 0.0
    if t <= ta:
        return x0 + s * a * t * t / 2, s * a * t
    if t <= ta + tc:
        return x0 + s * (v * ta / 2 + v * (t - ta)), s * v
    if t <= 2 * ta + tc:
        u = 2 * ta + tc - t
        return x1 - s * a * u * u / 2, s * a * u
    return x1, 0.0


@pytest.mark.parametrize(("target", "speed", "acc"), [(10.0, 100.0, 150.0), (100.0, 20.0, 500.0),
                                                      (105.0, 420.0, 5000.0), (60.0, 50.0, 100.0)])
def test_preposition_follows_trapezoid(homed: Rig, target: float, speed: float, acc: float) -> None:
    homed.status(0x30, acceleration=acc)
    homed.status(0x21, flags=0, width=target, speed=speed)
    t0 = homed.clock.now
    x0 = 110.0
    for i in range(1, 200):
        homed.clock.set(t0 + i * 0.02)
        t = homed.clock.now - t0
        want_x, want_v = trapezoid(t, x0, target, speed, acc)
        assert homed.g.width() == pytest.approx(want_x, abs=0.01)
        assert homed.g.speed() == pytest.approx(want_v, abs=0.01)
        assert abs(homed.g.speed()) <= speed + 1e-9
        # the 43h / 44h readings are the same closed-form values (float32 on the wire)
        w = struct.unpack("<f", homed.call(0x43, flags=0, period_ms=0).params)[0]
        v = struct.unpack("<f", homed.call(0x44, flags=0, period_ms=0).params)[0]
        assert w == pytest.approx(want_x, abs=0.01)
        assert v == pytest.approx(want_v, abs=0.01)


def test_speed_clamped_to_device_limit(homed: Rig) -> None:
    homed.status(0x30, acceleration=5000.0)
    homed.status(0x21, flags=0, width=0.0, speed=10000.0)
    peak = 0.0
    for _ in range(100):
        homed.clock.advance(0.005)
        peak = max(peak, abs(homed.g.speed()))
    assert peak == pytest.approx(420.0)
    homed.run(5)
    homed.status(0x21, flags=0, width=100.0, speed=0.1)  # below minimum: clamped up to 5 mm/s
    homed.clock.advance(5)
    assert homed.g.speed() == pytest.approx(5.0)


def test_widths_sampled_by_auto_update_match_profile(homed: Rig) -> None:
    homed.call(0x43, flags=1, period_ms=10)
    homed.status(0x30, acceleration=150.0)
    t0 = homed.clock.now
    homed.status(0x21, flags=0, width=30.0, speed=80.0)
    stamps: list[tuple[float, float]] = []
    homed.s.deliver = lambda f: stamps.append((homed.clock.now, struct.unpack("<f", f.params)[0])) \
        if f.command_id == 0x43 else None
    homed.run(2.0)
    assert len(stamps) >= 190
    for t, w in stamps:
        assert w == pytest.approx(trapezoid(t - t0, 110.0, 30.0, 80.0, 150.0)[0], abs=0.01)


@settings(max_examples=200, deadline=None)
@given(x0=st.floats(0, 110), x1=st.floats(0, 110), v=st.floats(5, 420), a=st.floats(100, 5000),
       frac=st.floats(0, 1.2))
def test_plan_move_matches_reference(x0: float, x1: float, v: float, a: float, frac: float) -> None:
    tr = plan_move(1.0, x0, x1, v, a)
    t = 1.0 + frac * (tr.end_time - 1.0)
    want_x, want_v = trapezoid(t - 1.0, x0, x1, v, a)
    assert tr.position(t) == pytest.approx(want_x, abs=1e-6)
    assert tr.velocity(t) == pytest.approx(want_v, abs=1e-6)
    assert abs(tr.velocity(t)) <= v + 1e-9
    assert tr.position(tr.end_time + 1) == pytest.approx(x1, abs=1e-9)


def test_first_crossing_solves_contact_time() -> None:
    tr = plan_move(0.0, 100.0, 0.0, 100.0, 1000.0)
    t = tr.first_crossing(40.0, -1)
    assert t is not None and tr.position(t) == pytest.approx(40.0, abs=1e-9)
    assert tr.first_crossing(40.0, +1) is None
    assert tr.first_crossing(-5.0, -1) is None


def test_stop_and_velocity_plans() -> None:
    st_ = plan_stop(0.0, 50.0, -100.0, 1000.0)
    assert st_.end_time == pytest.approx(0.1) and st_.position(1) == pytest.approx(45.0)
    vel = plan_velocity(0.0, 50.0, 0.0, 20.0, 100.0)
    assert vel.velocity(0.1) == pytest.approx(10.0) and vel.velocity(5.0) == pytest.approx(20.0)
    assert vel.position(1.0) == pytest.approx(50.0 + 2.0 + 16.0)
    assert math.isinf(vel.end_time)
    moving = plan_move(0.0, 50.0, 80.0, 50.0, 500.0, v0=-20.0)  # brake first, then move
    assert moving.position(moving.end_time) == 80.0
    assert moving.position(0.04) < 50.0


def test_grip_contact_time_and_width(homed: Rig) -> None:
    homed.g.faults.place_part(40.0, stiffness=400.0)
    homed.status(0x25, width=40.0, speed=100.0)
    t0 = homed.clock.now
    homed.run(5.0)
    # contact at the instant the profile reaches 40 mm; squeezed by F/k = 80/400 = 0.2 mm
    assert homed.width() == pytest.approx(39.8, abs=1e-4)
    tr = plan_move(t0, 110.0, 35.0, 100.0, 150.0)
    t_contact = tr.first_crossing(40.0, -1)
    assert t_contact is not None
    assert homed.g.log  # something logged
    assert homed.deferred[-1].status == 0
