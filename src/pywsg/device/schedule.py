"""The device's event schedule: timers, the next internal event, and "something changed" bookkeeping.

Nothing here reads a clock or sleeps: times are passed in (seconds on the device's clock). The
device asks :class:`Schedule` for the earliest due time; a server's runner is told through the
wake-up listeners whenever that time may have moved earlier.
"""

from __future__ import annotations

import heapq
import math
from collections.abc import Callable

Timer = tuple[float, int, str, tuple[object, ...]]  # (time, sequence, kind, arguments)


class Schedule:
    """Timers in time order, the next internal event time, a change counter and wake-up listeners.

    ``version`` counts state changes (change-only auto-updates look again only when it moved);
    ``due_valid`` / ``due_cache`` memoise :meth:`VirtualGripper.next_due` until the next change.
    """

    __slots__ = ("_seq", "_timers", "due_cache", "due_valid", "listeners", "next_event", "version")

    def __init__(self) -> None:
        self._timers: list[Timer] = []
        self._seq = 0
        self.next_event = math.inf  # clock time of the next internal event (motion, timer, temperature)
        self.version = 0
        self.due_valid = False
        self.due_cache: float | None = None
        self.listeners: list[Callable[[], None]] = []

    def changed(self) -> None:
        """State changed: change-only subscribers must look, and the due time may move."""
        self.version += 1
        self.due_valid = False

    def notify(self) -> None:
        """Tell the runners that the next due time may have moved earlier."""
        for fn in list(self.listeners):
            fn()

    def add_timer(self, t: float, kind: str, args: tuple[object, ...]) -> None:
        self._seq += 1
        heapq.heappush(self._timers, (t, self._seq, kind, args))

    def next_timer(self) -> float:
        """Time of the earliest timer (inf: none)."""
        return self._timers[0][0] if self._timers else math.inf

    def pop_timer(self) -> Timer:
        return heapq.heappop(self._timers)
