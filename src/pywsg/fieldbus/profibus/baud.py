"""Baud-rate detection of a DP slave, sans-IO: listen at one rate after another, lock to the rate at
which a telegram is read whole, and search again when the line stays silent (003 §6: "Profibus
Bitrate (automatically detected)").

The search runs from the highest declared rate down, as DP slave ASICs do; at each rate the slave
listens ``dwell_s`` seconds. Only a telegram whose delimiters, length and FCS are right counts: at a
wrong rate a UART reads garbage (mostly parity errors, dropped), and garbage does not pass an FCS.
Two such telegrams at one rate lock it (the caller flushes the port's input at each switch, so
bytes received at the rate before are never credited to the new one; the second telegram guards
against the one that slipped in between).
Once locked, ``hold_s`` seconds without such a telegram (the watchdog time when Set_Prm turned the
watchdog on) start the search again. Times are monotonic seconds passed in by the caller.
"""

from __future__ import annotations

from collections.abc import Iterable

#: Seconds at each rate while searching (a DP master sends a telegram every few ms even when it
#: talks to other stations: FDL status requests for its live list, tokens, Data_Exchange).
DWELL_S = 0.25
#: Seconds without a good telegram before a locked slave searches again (watchdog off).
HOLD_S = 3.0
#: Good telegrams at one rate that lock it.
LOCK_AFTER = 2


class BaudSearch:
    """Which rate to listen at now. Feed :meth:`heard` with each good telegram and call :meth:`tick`
    (at least every ``dwell_s``); a rate returned by either is the one to switch the port to."""

    def __init__(self, rates: Iterable[int], now: float, *, dwell_s: float = DWELL_S,
                 hold_s: float = HOLD_S) -> None:
        self.rates = sorted(set(rates), reverse=True)
        if not self.rates:
            raise ValueError("no baud rate to search")
        self.dwell_s = dwell_s
        self.hold_s = hold_s
        self.index = 0
        self.locked = False
        self.searches = 1          # times the search (re)started
        self._good = 0             # good telegrams at this rate since listening at it
        self._since = now          # listening at this rate since
        self._heard = now          # last good telegram

    @property
    def rate(self) -> int:
        """The rate listened at now (bit/s)."""
        return self.rates[self.index]

    def heard(self, now: float) -> None:
        """A good telegram was read at :attr:`rate`: the second one locks it (or it stays locked)."""
        self._heard = now
        self._good += 1
        if self._good >= LOCK_AFTER:
            self.locked = True

    def tick(self, now: float, hold_s: float | None = None) -> int | None:
        """The rate to switch to now, or None to stay. ``hold_s`` overrides the silence allowed
        while locked (the slave's watchdog time)."""
        if self.locked:
            if now - self._heard < (hold_s if hold_s is not None else self.hold_s):
                return None
            self.locked = False
            self.searches += 1
            self.index = 0
        elif now - self._since < self.dwell_s:
            return None
        else:
            self.index = (self.index + 1) % len(self.rates)
        self._since = now
        self._good = 0
        return self.rate
