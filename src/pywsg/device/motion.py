"""Closed-form finger motion: piecewise constant acceleration, evaluated at any time.

A :class:`Trajectory` is a list of phases; position and velocity at time ``t`` are computed
directly (no fixed-rate loop). Trapezoidal moves, stops and velocity ramps are built here, and
:meth:`Trajectory.first_crossing` finds when the fingers reach a width (contact with a part, a
soft limit, an end stop) by solving the phase's quadratic.

Units: time s, width mm, velocity mm/s (of the opening width), acceleration mm/s².
"""

from __future__ import annotations

import math
from dataclasses import dataclass

_EPS = 1e-9


@dataclass(frozen=True, slots=True)
class Phase:
    """Constant acceleration ``a`` from ``t0`` (width ``x0``, velocity ``v0``) until ``t1``."""

    t0: float
    x0: float
    v0: float
    a: float
    t1: float

    def x(self, t: float) -> float:
        dt = t - self.t0
        return self.x0 + self.v0 * dt + 0.5 * self.a * dt * dt

    def v(self, t: float) -> float:
        return self.v0 + self.a * (t - self.t0)


class Trajectory:
    """Width as a function of time. Before the first phase and after the last the fingers rest."""

    __slots__ = ("end_time", "final_x", "phases", "start_time", "start_x")

    def __init__(self, phases: list[Phase], start_time: float, start_x: float) -> None:
        self.phases = phases
        self.start_time = start_time
        self.start_x = start_x
        if phases:
            last = phases[-1]
            self.end_time = last.t1
            self.final_x = last.x(last.t1) if math.isfinite(last.t1) else math.nan
        else:
            self.end_time = start_time
            self.final_x = start_x

    @classmethod
    def rest(cls, t: float, x: float) -> Trajectory:
        """Fingers standing still at ``x``."""
        return cls([], t, x)

    @property
    def moving(self) -> bool:
        return bool(self.phases)

    def _phase(self, t: float) -> Phase | None:
        for ph in self.phases:
            if t < ph.t1:
                return ph if t >= ph.t0 else None
        return None

    def position(self, t: float) -> float:
        if not self.phases or t <= self.start_time:
            return self.start_x
        if t >= self.end_time:
            return self.final_x
        ph = self._phase(t)
        return ph.x(t) if ph is not None else self.start_x

    def velocity(self, t: float) -> float:
        # at the start itself the first phase's v0: a motion planned from a moving state carries its speed
        if not self.phases or t < self.start_time or t >= self.end_time:
            return 0.0
        ph = self._phase(t)
        return ph.v(t) if ph is not None else 0.0

    def is_moving(self, t: float) -> bool:
        return bool(self.phases) and self.start_time <= t < self.end_time

    def first_crossing(self, p: float, direction: int, after: float | None = None) -> float | None:
        """Earliest time >= ``after`` at which the width reaches ``p`` moving in ``direction``.

        ``direction`` -1: closing onto ``p`` from above; +1: opening onto ``p`` from below.
        Touching ``p`` at the very start while already moving towards it counts as a crossing.
        """
        for ph in self.phases:
            if after is not None and ph.t1 <= after:
                continue
            t = _phase_crossing(ph, p, direction, after)
            if t is not None:
                return t
        return None


def _phase_crossing(ph: Phase, p: float, direction: int, after: float | None) -> float | None:
    lo = ph.t0 if after is None else max(ph.t0, after)
    duration = ph.t1 - ph.t0
    # width relative to p along the phase: c + b*dt + a/2*dt^2
    c = ph.x0 - p
    b = ph.v0
    a = ph.a
    roots: list[float] = []
    if abs(a) < _EPS:
        if abs(b) > _EPS:
            roots.append(-c / b)
    else:
        disc = b * b - 2.0 * a * c
        if disc >= 0:
            sq = math.sqrt(disc)
            roots.extend(((-b - sq) / a, (-b + sq) / a))
    best: float | None = None
    for r in roots:
        # allow a tiny negative root: the fingers start exactly at p
        if r < -1e-9 or r > duration + 1e-12:
            continue
        r = max(r, 0.0)
        t = ph.t0 + r
        if t < lo - 1e-12:
            continue
        v = ph.v0 + a * r
        if v * direction <= 0 and not (abs(v) < _EPS and a * direction > 0):
            continue
        if best is None or t < best:
            best = t
    return best


def plan_move(t0: float, x0: float, target: float, vmax: float, acc: float, v0: float = 0.0) -> Trajectory:
    """Trapezoidal (or triangular) move from ``x0`` to ``target`` with peak speed ``vmax``.

    If the fingers are moving (``v0`` != 0) they first brake to rest with ``acc``, then move.
    """
    phases: list[Phase] = []
    t, x = t0, x0
    if abs(v0) > _EPS:
        stop = plan_stop(t0, x0, v0, acc)
        phases.extend(stop.phases)
        t, x = stop.end_time, stop.final_x
    d = target - x
    dist = abs(d)
    if dist < 1e-12 or vmax <= 0 or acc <= 0:
        return Trajectory(phases, t0, x0) if phases else Trajectory.rest(t0, x0)
    s = 1.0 if d > 0 else -1.0
    if dist <= vmax * vmax / acc:  # triangle: never reaches vmax
        tp = math.sqrt(dist / acc)
        vp = acc * tp
        phases.append(Phase(t, x, 0.0, s * acc, t + tp))
        phases.append(Phase(t + tp, x + s * dist / 2, s * vp, -s * acc, t + 2 * tp))
    else:
        ta = vmax / acc
        da = vmax * vmax / (2 * acc)
        tc = (dist - 2 * da) / vmax
        phases.append(Phase(t, x, 0.0, s * acc, t + ta))
        phases.append(Phase(t + ta, x + s * da, s * vmax, 0.0, t + ta + tc))
        phases.append(Phase(t + ta + tc, x + s * (dist - da), s * vmax, -s * acc, t + 2 * ta + tc))
    # pin the end exactly on the target (float rounding)
    return _pinned(Trajectory(phases, t0, x0), target)


def _pinned(tr: Trajectory, target: float) -> Trajectory:
    tr.final_x = target
    return tr


def plan_stop(t0: float, x0: float, v0: float, acc: float) -> Trajectory:
    """Brake from velocity ``v0`` to rest with deceleration ``acc``."""
    if abs(v0) < _EPS or acc <= 0:
        return Trajectory.rest(t0, x0)
    s = 1.0 if v0 > 0 else -1.0
    ts = abs(v0) / acc
    return Trajectory([Phase(t0, x0, v0, -s * acc, t0 + ts)], t0, x0)


def plan_velocity(t0: float, x0: float, v0: float, v_target: float, acc: float) -> Trajectory:
    """Ramp from ``v0`` to ``v_target`` with ``acc`` and keep that velocity (no end: a jog).

    The caller ends it with an event (end stop, soft limit, contact) or a new plan.
    """
    phases: list[Phase] = []
    t, x, v = t0, x0, v0
    dv = v_target - v0
    if abs(dv) > _EPS and acc > 0:
        s = 1.0 if dv > 0 else -1.0
        tr = abs(dv) / acc
        ph = Phase(t, x, v, s * acc, t + tr)
        phases.append(ph)
        t, x, v = ph.t1, ph.x(ph.t1), v_target
    if abs(v) > _EPS:
        phases.append(Phase(t, x, v, 0.0, math.inf))
    if not phases:
        return Trajectory.rest(t0, x0)
    return Trajectory(phases, t0, x0)
