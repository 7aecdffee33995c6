"""Timing: one timer for the whole process, and a :class:`DeviceRunner` per virtual gripper.

The virtual gripper is sans-IO: ``next_due()`` says when its next event falls due (the final reply of
a motion, an auto-update packet, a temperature step) and ``poll()`` hands out what is due. A runner
keeps its gripper's next due time in the :class:`Scheduler`'s heap; the scheduler arms **one** loop
timer for the earliest entry of all grippers and streams. No fixed tick and no busy loop: an idle
gripper with no subscriptions has no entry at all.

Precision. The stock asyncio loop waits in ``epoll`` with a timeout rounded *up* to whole
milliseconds and then often sleeps a second millisecond when it woke a hair early, so
``asyncio.sleep`` is ~1.2 ms late (p99 ~2.2 ms). The scheduler therefore arms its timer ``early``
seconds before the due time and sleeps the rest with :func:`time.sleep` (nanosecond timer, no CPU),
which puts the wakeup within ~0.1–0.7 ms of the due time. The blocking part is at most ``early`` plus
the loop's lateness. Only grippers on a real-time clock are put on the timer. Events due within one such wakeup are
served together, and frames for one connection are written in one ``write`` after the round.
"""

from __future__ import annotations

import asyncio
import heapq
import itertools
import logging
import time
from collections.abc import Callable
from typing import Any, Protocol

from .device_api import GripperLike

log = logging.getLogger(__name__)

MAX_ROUND = 0.004
"""Longest time (s) one scheduler round may take before it lets the loop serve sockets."""


class Flushable(Protocol):
    """A connection that collects frames during a scheduler round and writes them after it."""

    def flush(self) -> None: ...


def _is_uvloop(loop: asyncio.AbstractEventLoop) -> bool:
    return type(loop).__module__.startswith("uvloop")


def default_early(loop: asyncio.AbstractEventLoop | None = None) -> float:
    """Seconds to wake before a due time: covers the loop's own lateness (see module docstring)."""
    if _is_uvloop(loop or asyncio.get_running_loop()):
        return 0.0012  # libuv timers have whole-millisecond resolution
    return 0.0016


class Scheduler:
    """A heap of due times (``time.monotonic`` seconds) served by one loop timer.

    One per event loop (:func:`get_scheduler`); all grippers of a process share it.
    """

    def __init__(self, loop: asyncio.AbstractEventLoop | None = None, early: float | None = None) -> None:
        self.loop = loop or asyncio.get_running_loop()
        self.early = default_early(self.loop) if early is None else early
        # libuv measures timers from a loop time cached at the start of an iteration, so a uvloop
        # timer may fire up to ~1 ms before its time: accept that much more before re-arming
        self.slack = 0.0015 if _is_uvloop(self.loop) else 0.0002
        self._heap: list[tuple[float, int, DeviceRunner]] = []
        self._seq = itertools.count()
        self._handle: asyncio.TimerHandle | None = None
        self._armed_for = float("inf")
        self._dirty: dict[int, Flushable] = {}
        self.in_round = False
        self.rounds = 0
        """Timer wakeups so far (for tests: an idle gripper must not add any)."""

    # -- entries ---------------------------------------------------------------------------
    def schedule(self, runner: DeviceRunner, when: float) -> None:
        """Queue ``runner`` at monotonic time ``when``; replaces its previous entry."""
        seq = next(self._seq)
        runner._entry = seq
        runner._entry_when = when
        heapq.heappush(self._heap, (when, seq, runner))
        if not self.in_round and when < self._armed_for:
            self._arm()

    def cancel(self, runner: DeviceRunner) -> None:
        runner._entry = None  # lazily dropped from the heap
        runner._entry_when = float("inf")

    @property
    def pending(self) -> int:
        """Live entries in the heap."""
        return sum(1 for _, seq, r in self._heap if r._entry == seq)

    def _arm(self) -> None:
        heap = self._heap
        while heap and heap[0][2]._entry != heap[0][1]:
            heapq.heappop(heap)
        if self._handle is not None:
            self._handle.cancel()
            self._handle = None
        if not heap:
            self._armed_for = float("inf")
            return
        when = heap[0][0]
        self._armed_for = when
        delay = when - time.monotonic() - self.early
        self._handle = self.loop.call_at(self.loop.time() + max(delay, 0.0), self._fire)

    # -- output coalescing -----------------------------------------------------------------
    def mark_dirty(self, conn: Flushable) -> None:
        """``conn`` has frames to write at the end of this round."""
        self._dirty[id(conn)] = conn

    def flush(self) -> None:
        dirty = self._dirty
        if not dirty:
            return
        self._dirty = {}
        for conn in dirty.values():
            try:
                conn.flush()
            except Exception:  # one broken connection must not stop the others
                log.exception("flushing %r failed", conn)

    # -- the round -------------------------------------------------------------------------
    def _fire(self) -> None:
        self._handle = None
        self._armed_for = float("inf")
        self.rounds += 1
        heap = self._heap
        self.in_round = True
        start = time.monotonic()
        try:
            while heap:
                when, seq, runner = heap[0]
                if runner._entry != seq:
                    heapq.heappop(heap)
                    continue
                now = time.monotonic()
                wait = when - now
                if wait > 0:
                    # close enough to sleep precisely here; else leave it to the next timer
                    if wait > self.early + self.slack or now - start > MAX_ROUND:
                        break
                    time.sleep(wait)
                heapq.heappop(heap)
                runner._entry = None
                runner._entry_when = float("inf")
                runner.run()
        finally:
            self.in_round = False
            self.flush()
            self._arm()

    def close(self) -> None:
        if self._handle is not None:
            self._handle.cancel()
            self._handle = None
        self._heap.clear()
        self._armed_for = float("inf")


_SCHEDULERS: dict[int, Scheduler] = {}


def get_scheduler(loop: asyncio.AbstractEventLoop | None = None) -> Scheduler:
    """The process-wide scheduler of ``loop`` (the running loop by default)."""
    loop = loop or asyncio.get_running_loop()
    sched = _SCHEDULERS.get(id(loop))
    if sched is None or sched.loop is not loop or loop.is_closed():
        sched = Scheduler(loop)
        _SCHEDULERS[id(loop)] = sched
    return sched


def _clock_of(gripper: GripperLike) -> Callable[[], float]:
    clock: Any = getattr(gripper, "clock", None)
    return clock if callable(clock) else time.monotonic


def is_realtime(clock: Callable[[], float]) -> bool:
    """True for clocks that follow :func:`time.monotonic` (False for ``ManualClock`` and the like)."""
    if clock is time.monotonic or getattr(clock, "realtime", False):
        return True
    try:
        from ..device.clock import ManualClock, monotonic_clock
    except ImportError:  # pragma: no cover - the device package is part of pywsg
        ManualClock, monotonic_clock = None, None  # type: ignore[assignment,misc]
    if clock is monotonic_clock:
        return True
    if ManualClock is not None and isinstance(clock, ManualClock):
        return False
    return abs(clock() - time.monotonic()) < 0.01


class DeviceRunner:
    """Serves one gripper's due events on time.

    ``start()`` registers the gripper's wakeup listener and queues its first due time; after each
    ``poll()`` the next due time is queued again. Frames reach the clients through the sessions'
    ``deliver`` callbacks, which the transports set. A gripper on an injected clock that does not
    follow real time (:class:`~pywsg.device.ManualClock`) is never put on the timer: tests advance
    the clock and call :meth:`poll_now` to serve what became due.
    """

    def __init__(
        self, gripper: GripperLike, scheduler: Scheduler | None = None, realtime: bool | None = None
    ) -> None:
        self.gripper = gripper
        self.scheduler = scheduler
        self.clock = _clock_of(gripper)
        self.realtime = is_realtime(self.clock) if realtime is None else realtime
        self.polls = 0
        self._entry: int | None = None
        self._entry_when = float("inf")
        self._running = False
        self._started = False

    def start(self) -> None:
        if self._started:
            return
        if self.scheduler is None:
            self.scheduler = get_scheduler()
        self._started = True
        self.gripper.add_wakeup_listener(self.wake)
        self.wake()

    def stop(self) -> None:
        self._started = False
        if self.scheduler is not None:
            self.scheduler.cancel(self)

    def wake(self) -> None:
        """The gripper's next due time may have moved earlier: re-queue if so."""
        if not self._started or self._running or self.scheduler is None or not self.realtime:
            return
        due = self.gripper.next_due()
        if due is None:
            return
        when = self._to_monotonic(due)
        if when < self._entry_when:
            self.scheduler.schedule(self, when)

    def _to_monotonic(self, due: float) -> float:
        if self.clock is time.monotonic:
            return due
        return time.monotonic() + (due - self.clock())  # same rate, maybe another origin

    def run(self) -> None:
        """Poll the gripper (sessions' deliver callbacks get the frames) and queue the next due time."""
        self._running = True
        try:
            self.gripper.poll()
            self.polls += 1
        finally:
            self._running = False
        if not self._started or self.scheduler is None or not self.realtime:
            return
        due = self.gripper.next_due()
        if due is None:
            return
        now = self.clock()
        if due <= now:
            # poll() should have served it; do not spin on a due time that stays in the past
            log.debug("next_due %.6f not after poll at %.6f", due, now)
            due = now + 0.0005
        self.scheduler.schedule(self, self._to_monotonic(due))

    def poll_now(self) -> None:
        """Serve whatever is due at the gripper's clock now and write it out (tests, manual clocks)."""
        sched = self.scheduler
        if sched is not None:
            sched.cancel(self)
            was = sched.in_round
            sched.in_round = True
            try:
                self.run()
            finally:
                sched.in_round = was
                if not was:
                    sched.flush()
                    sched._arm()
        else:
            self.run()
