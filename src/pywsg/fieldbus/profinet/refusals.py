"""Rate-limited logging of refused packets: a flood of bad requests must not flood the log.

At most :data:`BURST` WARNING lines per :data:`WINDOW_S` seconds; the rest are counted and the next line
that is logged says how many were left out. Each refusal is still answered on the wire.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable

BURST = 10
WINDOW_S = 10.0


class RefusalLog:
    """``warn(fmt, *args)`` as ``logger.warning``, bounded to ``burst`` lines per ``window`` seconds."""

    def __init__(self, logger: logging.Logger, burst: int = BURST, window: float = WINDOW_S,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.logger = logger
        self.burst, self.window, self.clock = burst, window, clock
        self._start = float("-inf")
        self._lines = 0
        self.suppressed = 0    # lines left out since the last one logged
        self.total = 0         # refusals seen

    def warn(self, fmt: str, *args: object) -> None:
        self.total += 1
        now = self.clock()
        if now - self._start >= self.window:
            self._start, self._lines = now, 0
        if self._lines >= self.burst:
            self.suppressed += 1
            return
        self._lines += 1
        if self.suppressed:
            fmt += " (%d more refused since, not logged)"
            args = (*args, self.suppressed)
            self.suppressed = 0
        self.logger.warning(fmt, *args)
