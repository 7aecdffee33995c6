"""Timing: one timer for the whole process, and a :class:`DeviceRunner` per virtual gripper.

The virtual gripper is sans-IO: ``next_due()`` says when its next event falls due (the final reply of
a motion, an auto-update packet, a temperature step) and ``poll()`` hands out what is due. A runner
keeps its gripper's next due time in the :class:`Scheduler`'s heap; the scheduler arms **one** timer
for the earliest entry of all grippers and streams. No fixed tick and no busy loop: an idle gripper
with no subscriptions has no entry at all.

Precision without blocking. The stock asyncio loop waits in ``epoll`` with a timeout rounded *up* to
whole milliseconds (libuv timers too), so a loop timer is ~1–2 ms late. The scheduler's timer is
therefore not a loop timer: on Linux it is a ``timerfd`` (``CLOCK_MONOTONIC``, absolute expiry with
nanosecond resolution) that the loop watches like a socket, so ``epoll`` itself returns when the due
time comes — typically within ~0.05–0.1 ms — and the loop thread never sleeps: requests arriving
just before a due time are answered at once. Elsewhere a helper thread waits precisely (the wait
releases the GIL) and wakes the loop with ``call_soon_threadsafe``. Events due by the time a round
runs are served together, and frames for one connection are written in one ``write`` after the round.
"""

from __future__ import annotations

import asyncio
import ctypes
import heapq
import itertools
import logging
import math
import os
import sys
import threading
import time
from collections.abc import Callable
from typing import Any, Protocol

from .device_api import GripperLike

log = logging.getLogger(__name__)

MAX_ROUND = 0.004
"""Longest time (s) one scheduler round may take before it lets the loop serve sockets."""

MIN_ROUND_GAP = 0.0002
"""Shortest time (s) from the end of one round to the next wakeup. Streams of many grippers fall due
at many slightly different times; without a gap each would cost a wakeup of its own (epoll return,
timer read and re-arm). Entries due within the gap are served together, at most this much later —
a delay that is nearly the same from one packet of a stream to the next, so intervals keep."""


class Flushable(Protocol):
    """A connection that collects frames during a scheduler round and writes them after it."""

    def flush(self) -> None: ...


class Waker(Protocol):
    """Calls back on the loop thread at an absolute ``time.monotonic()`` time."""

    def arm(self, when: float) -> None: ...

    def disarm(self) -> None: ...

    def close(self) -> None: ...


# -- Linux: timerfd watched by the loop ----------------------------------------------------------

class _Timespec(ctypes.Structure):
    _fields_ = [("tv_sec", ctypes.c_long), ("tv_nsec", ctypes.c_long)]


class _Itimerspec(ctypes.Structure):
    _fields_ = [("it_interval", _Timespec), ("it_value", _Timespec)]


_CLOCK_MONOTONIC = 1
_TFD_NONBLOCK = os.O_NONBLOCK
_TFD_CLOEXEC = getattr(os, "O_CLOEXEC", 0)
_TFD_TIMER_ABSTIME = 1
_libc: Any = None


def _timerfd_libc() -> Any:
    """libc with timerfd_create/timerfd_settime, or None (not Linux, or time.monotonic is another clock)."""
    global _libc
    if _libc is None:
        _libc = False
        impl = time.get_clock_info("monotonic").implementation
        if sys.platform.startswith("linux") and "CLOCK_MONOTONIC" in impl and "RAW" not in impl:
            try:
                libc = ctypes.CDLL(None, use_errno=True)
                libc.timerfd_create.argtypes = [ctypes.c_int, ctypes.c_int]
                libc.timerfd_settime.argtypes = [
                    ctypes.c_int, ctypes.c_int, ctypes.POINTER(_Itimerspec), ctypes.c_void_p
                ]
                _libc = libc
            except (OSError, AttributeError):
                pass
    return _libc or None


def timerfd_available() -> bool:
    return _timerfd_libc() is not None


class TimerFdWaker:
    """A ``timerfd`` on ``CLOCK_MONOTONIC`` (what :func:`time.monotonic` reads) in the loop's selector.

    The fd exists only while armed, so an idle process holds none and a closed loop leaks none.
    """

    def __init__(self, loop: asyncio.AbstractEventLoop, callback: Callable[[], None]) -> None:
        self._libc = _timerfd_libc()
        if self._libc is None:
            raise OSError("timerfd not available")
        self.loop = loop
        self.callback = callback
        self.fd = -1
        self._spec = _Itimerspec()
        self._spec_ref = ctypes.byref(self._spec)

    def arm(self, when: float) -> None:
        if self.fd < 0:
            fd = self._libc.timerfd_create(_CLOCK_MONOTONIC, _TFD_NONBLOCK | _TFD_CLOEXEC)
            if fd < 0:
                err = ctypes.get_errno()
                raise OSError(err, os.strerror(err))
            self.fd = fd
            self.loop.add_reader(fd, self._readable)
        sec = math.floor(when)
        ns = int((when - sec) * 1e9)
        if sec <= 0 and ns <= 0:
            ns = 1  # a zero expiry would disarm
        value = self._spec.it_value
        value.tv_sec = sec
        value.tv_nsec = ns
        if self._libc.timerfd_settime(self.fd, _TFD_TIMER_ABSTIME, self._spec_ref, None) < 0:
            err = ctypes.get_errno()
            raise OSError(err, os.strerror(err))

    def disarm(self) -> None:
        self.close()

    def _readable(self) -> None:
        try:
            os.read(self.fd, 8)
        except (BlockingIOError, InterruptedError):
            return  # re-armed after it expired: not due yet
        self.callback()

    def close(self) -> None:
        if self.fd >= 0:
            fd, self.fd = self.fd, -1
            if not self.loop.is_closed():
                self.loop.remove_reader(fd)
            os.close(fd)


# -- elsewhere: a helper thread that waits precisely ----------------------------------------------

class ThreadWaker:
    """A daemon thread waits until the due time (the wait releases the GIL), then wakes the loop."""

    def __init__(self, loop: asyncio.AbstractEventLoop, callback: Callable[[], None]) -> None:
        self.loop = loop
        self.callback = callback
        self._cond = threading.Condition()
        self._when = math.inf
        self._closed = False
        self._thread: threading.Thread | None = None

    def arm(self, when: float) -> None:
        with self._cond:
            self._when = when
            self._cond.notify()
        if self._thread is None:
            self._thread = threading.Thread(target=self._run, name="pywsg-scheduler", daemon=True)
            self._thread.start()

    def disarm(self) -> None:
        with self._cond:
            self._when = math.inf
            self._cond.notify()

    def _run(self) -> None:
        cond = self._cond
        with cond:
            while not self._closed:
                when = self._when
                if when == math.inf:
                    cond.wait()
                    continue
                wait = when - time.monotonic()
                if wait > 0:
                    cond.wait(wait)
                    continue
                self._when = math.inf
                try:
                    self.loop.call_soon_threadsafe(self._fire)
                except RuntimeError:  # loop closed
                    return

    def _fire(self) -> None:
        if not self._closed:
            self.callback()

    def close(self) -> None:
        with self._cond:
            self._closed = True
            self._cond.notify()
        self._thread = None


def make_waker(
    loop: asyncio.AbstractEventLoop, callback: Callable[[], None], kind: str | None = None
) -> Waker:
    """``kind``: ``"timerfd"``, ``"thread"`` or None (timerfd where available, else thread)."""
    if kind is None:
        kind = os.environ.get("PYWSG_SCHEDULER_TIMER") or ("timerfd" if timerfd_available() else "thread")
    if kind == "timerfd":
        return TimerFdWaker(loop, callback)
    if kind == "thread":
        return ThreadWaker(loop, callback)
    raise ValueError(f"unknown timer kind {kind!r}")


class Scheduler:
    """A heap of due times (``time.monotonic`` seconds) served by one precise timer.

    One per event loop (:func:`get_scheduler`); all grippers of a process share it.
    """

    def __init__(self, loop: asyncio.AbstractEventLoop | None = None, timer: str | None = None) -> None:
        self.loop = loop or asyncio.get_running_loop()
        self.waker = make_waker(self.loop, self._fire, timer)
        self.timer = "timerfd" if isinstance(self.waker, TimerFdWaker) else "thread"
        self._heap: list[tuple[float, int, DeviceRunner]] = []
        self._seq = itertools.count()
        self._armed_for = math.inf
        self._not_before = 0.0
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
        runner._entry_when = math.inf
        if not self.in_round:
            self._arm()  # drops the timer when nothing else is queued

    @property
    def pending(self) -> int:
        """Live entries in the heap."""
        return sum(1 for _, seq, r in self._heap if r._entry == seq)

    @property
    def armed(self) -> bool:
        """True while the timer is set (it is off when nothing is queued)."""
        return self._armed_for != math.inf

    def _arm(self) -> None:
        heap = self._heap
        while heap and heap[0][2]._entry != heap[0][1]:
            heapq.heappop(heap)
        if not heap:
            self._armed_for = math.inf
            self.waker.disarm()  # also after it fired: the timerfd is closed with the last entry
            return
        when = heap[0][0]
        if when < self._not_before:
            when = self._not_before
        if when != self._armed_for:
            self._armed_for = when
            self.waker.arm(when)

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
        self._armed_for = math.inf
        self.rounds += 1
        heap = self._heap
        self.in_round = True
        clock = time.monotonic
        start = now = clock()
        try:
            while heap:
                when, seq, runner = heap[0]
                if runner._entry != seq:
                    heapq.heappop(heap)
                    continue
                if when > now:
                    break  # not due yet: the timer wakes the loop for it
                heapq.heappop(heap)
                runner._entry = None
                runner._entry_when = math.inf
                runner.run()
                now = clock()
                if now - start > MAX_ROUND:
                    break  # a long round lets the loop serve sockets; the timer is re-armed at once
        finally:
            self.in_round = False
            self.flush()
            self._not_before = clock() + MIN_ROUND_GAP
            self._arm()

    def close(self) -> None:
        self._heap.clear()
        self._armed_for = math.inf
        self.waker.close()


_SCHEDULERS: dict[int, Scheduler] = {}


def get_scheduler(loop: asyncio.AbstractEventLoop | None = None) -> Scheduler:
    """The process-wide scheduler of ``loop`` (the running loop by default)."""
    loop = loop or asyncio.get_running_loop()
    sched = _SCHEDULERS.get(id(loop))
    if sched is None or sched.loop is not loop or loop.is_closed():
        if sched is not None:
            sched.close()  # a stale scheduler of a closed loop that had the same id
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


def _is_monotonic_clock(clock: Callable[[], float]) -> bool:
    try:
        from ..device.clock import monotonic_clock
    except ImportError:  # pragma: no cover - the device package is part of pywsg
        return False
    return clock is monotonic_clock


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
        self._native = self.clock is time.monotonic or _is_monotonic_clock(self.clock)
        """The gripper's clock reads time.monotonic itself: due times need no conversion."""
        rate = getattr(self.clock, "rate", 1.0)
        self._rate = float(rate) if isinstance(rate, int | float) and rate > 0 else 1.0
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
        if self._native:
            return due
        # maybe another origin; a scaled clock (ScaledClock: ``rate`` device seconds per real second)
        return time.monotonic() + (due - self.clock()) / self._rate

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
