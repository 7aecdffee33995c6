"""What ``wsg proxy`` records of the traffic it relays: its counters and the comm log's rate.

The pcapng side is :class:`~pywsg.capture.pcap.PcapWriter` (streamed to disk, every byte); the comm log
gets at most ``log_rate`` entries a second (:class:`LogGate`), a line a second saying what was left out.
"""

from __future__ import annotations

import collections
import time
from dataclasses import dataclass, field

from ...capture.commlog import CommLog, TxRx

__all__ = ["LogGate", "ProxyStats"]


@dataclass
class ProxyStats:
    """Counters of one proxy run."""

    connections: int = 0
    frames: dict[str, int] = field(default_factory=lambda: {"tx": 0, "rx": 0})
    bytes: dict[str, int] = field(default_factory=lambda: {"tx": 0, "rx": 0})
    not_logged: int = 0  # frames over the log rate (in the pcapng, not in the comm log)


class LogGate:
    """At most ``rate`` comm-log entries a second for the whole proxy; what is left out is one line a
    second per direction (``0``: no limit). ``captured``: a pcapng file gets every byte (the line
    says so)."""

    def __init__(self, log: CommLog | None, rate: int, stats: ProxyStats, captured: bool = False) -> None:
        self.log = log
        self.rate = rate
        self.stats = stats
        self.captured = captured
        self.window = 0.0
        self.used = 0
        self.skipped: dict[TxRx, collections.Counter[str]] = {"tx": collections.Counter(),
                                                             "rx": collections.Counter()}

    def full(self) -> bool:
        """No entry would be shown now: no log, or this second's ``rate`` is spent."""
        if self.log is None:
            return True
        if not self.rate:
            return False
        self.roll()
        return self.used >= self.rate

    def roll(self) -> None:
        """Start a new second once the last one has ended (writing its 'not logged' lines)."""
        now = time.monotonic()
        if now - self.window >= 1.0:
            self.summary()
            self.window, self.used = now, 0

    def skip(self, direction: TxRx, what: str, n: int = 1) -> None:
        """``n`` frames of kind ``what`` left out (counted for the next 'not logged' line)."""
        if self.log is not None and n:
            self.skipped[direction][what] += n
            self.stats.not_logged += n

    def allow(self, direction: TxRx, what: str, n: int = 1) -> bool:
        """One entry may be shown now (it uses one of this second's ``rate``); if not, the ``n`` frames
        it stands for (of kind ``what``) are counted as left out."""
        if self.full():
            self.skip(direction, what, n)
            return False
        self.used += 1
        return True

    def summary(self) -> None:
        """Write the 'not logged' lines for the window just ended."""
        if self.log is None:
            return
        where = "; the pcapng has them" if self.captured else ""
        for direction, counts in self.skipped.items():
            if counts:
                total = sum(counts.values())
                top = ", ".join(f"{k} x{n}" for k, n in counts.most_common(4))
                self.log.note(direction, f"{total} frame(s) not logged (over {self.rate}/s{where}): {top}")
                counts.clear()
