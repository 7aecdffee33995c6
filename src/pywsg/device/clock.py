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


def monotonic_clock() -> float:
    """The real clock: :func:`time.monotonic` in seconds."""
    return time.monotonic()
