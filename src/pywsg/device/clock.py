"""Clocks for the virtual gripper. Time is in seconds (float), monotonic."""

from __future__ import annotations

import time
from collections.abc import Callable

Clock = Callable[[], float]
"""Any zero-argument callable returning the current time in seconds."""


class ManualClock:
    """A clock that only moves when told to: ``clock()`` reads it, ``advance(dt)`` moves it.

    Tests drive the virtual gripper with it so that a 2-second grip runs in microseconds.
    """

    __slots__ = ("now",)

    def __init__(self, start: float = 0.0) -> None:
        self.now = float(start)

    def __call__(self) -> float:
        return self.now

    def advance(self, dt: float) -> float:
        """Move the clock forward by ``dt`` seconds (must not be negative); returns the new time."""
        if dt < 0:
            raise ValueError("a clock cannot go backwards")
        self.now += dt
        return self.now

    def set(self, t: float) -> None:
        """Jump to ``t`` seconds (not earlier than now)."""
        if t < self.now:
            raise ValueError("a clock cannot go backwards")
        self.now = float(t)


class ScaledClock:
    """Real time run ``rate`` times faster: ``clock()`` = ``start`` + ``rate`` × (real seconds since creation).

    ``wsg sim --time-scale K`` and ``SimThread(time_scale=K)``: motion, homing, the thermal model,
    auto-update periods and scenario times all run on it, so a 2 s grip takes 2/K real seconds. The
    wire does not speed up (network faults and client timeouts stay in real seconds).
    """

    __slots__ = ("_real0", "rate", "start")

    realtime = True
    """It follows :func:`time.monotonic` (at a rate): the sim's scheduler puts its due times on the timer."""

    def __init__(self, rate: float, start: float = 0.0) -> None:
        if not (isinstance(rate, int | float) and 0 < rate < float("inf")):
            raise ValueError(f"time scale: must be a positive number, not {rate!r}")
        self.rate = float(rate)
        self.start = float(start)
        self._real0 = time.monotonic()

    def __call__(self) -> float:
        return self.start + (time.monotonic() - self._real0) * self.rate

    def to_real(self, dt: float) -> float:
        """Real seconds for ``dt`` seconds of this clock."""
        return dt / self.rate


def real_seconds(clock: object, dt: float) -> float:
    """Real seconds that ``dt`` seconds of ``clock`` take (``dt`` itself for a clock without a rate)."""
    rate = getattr(clock, "rate", 1.0)
    return dt / rate if isinstance(rate, int | float) and rate > 0 else dt


def monotonic_clock() -> float:
    """The real clock: :func:`time.monotonic` in seconds."""
    return time.monotonic()
