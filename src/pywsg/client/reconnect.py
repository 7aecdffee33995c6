"""The reconnect policy and its back-off, sans-IO (both drivers sleep and connect; this only counts).

A gripper that drops every connection soon after accepting it (a crashing server, a peer that
closes on an unexpected byte, a cell PLC that takes the gripper over) must not be reconnected to
forever at the first delay: every unannounced close raises FAST STOP on a WSG (000 §1.4.2). So a
connection counts as *stable* only after it lived ``stable_after`` s; until then a lost connection
continues the back-off where it stood (the delay keeps doubling and the attempts keep counting), and
after ``attempts`` the driver gives up. A stable connection starts the next loss afresh.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass


@dataclass
class ReconnectPolicy:
    """Opt-in automatic reconnection: ``attempts`` tries, ``delay`` s apart (doubling up to ``max_delay``).

    A connection that is lost within ``stable_after`` s of being made counts as a failed attempt:
    the delay goes on doubling and the attempts go on counting, so a gripper that accepts and then
    drops every connection is given up after ``attempts``."""

    attempts: int = 10
    delay: float = 0.2
    max_delay: float = 5.0
    stable_after: float = 5.0


class Backoff:
    """The reconnect schedule of one driver under ``policy``; ``clock`` in s (monotonic).

    The driver calls :meth:`connected` whenever a connection is made, :meth:`lost` when it drops,
    and :meth:`next_delay` before each attempt (None: give up)."""

    def __init__(self, policy: ReconnectPolicy, clock: Callable[[], float] = time.monotonic) -> None:
        self.policy = policy
        self._clock = clock
        self.attempt = 0  # attempts since the last stable connection
        self._delay = policy.delay
        self._connected_at: float | None = None
        self.gave_up = False

    def _reset(self) -> None:
        self.attempt = 0
        self._delay = self.policy.delay
        self.gave_up = False

    def connected(self) -> None:
        """A connection was made (by an attempt, or by the user: that one re-arms a driver that gave up)."""
        self._connected_at = self._clock()
        if self.gave_up:
            self._reset()

    def lost(self) -> None:
        """The connection dropped: after a stable one the schedule starts again from ``policy.delay``."""
        at, self._connected_at = self._connected_at, None
        if at is not None and self._clock() - at >= self.policy.stable_after:
            self._reset()

    def next_delay(self) -> float | None:
        """s to wait before the next attempt, or None when ``policy.attempts`` are used up."""
        if self.attempt >= self.policy.attempts:
            self.gave_up = True
            return None
        self.attempt += 1
        d = self._delay
        self._delay = min(d * 2, self.policy.max_delay)
        return d
