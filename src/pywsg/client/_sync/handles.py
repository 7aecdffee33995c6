"""What the blocking driver's calls hand back: :class:`Motion` (a running motion, ``wait=False``)
and :class:`Stream` (auto-update samples); :class:`Callbacks`, the thread that runs stream callbacks,
and :class:`Reader`, the background reader while streams run.

They see the shell through :class:`Host`, the few methods they call, never the
:class:`~pywsg.client.Gripper` class itself (so the shell imports them and not the other way round)."""

from __future__ import annotations

import collections
import logging
import queue
import threading
import time
from collections.abc import Callable, Iterator
from typing import Any, Protocol

from ...errors import TimeoutError
from ...protocol import Command, Frame, Status, SystemFlag
from ..calls import Call
from ..core import sample_of
from ..demux import Sink, Waiter
from ..motion import MotionBase
from ..types import Sample

#: s the background reader blocks at a time (how fast it notices stop())
READ_SLICE = 0.05


class Host(Protocol):
    """What the handles need from the blocking shell (:class:`~pywsg.client.Gripper` implements it)."""

    motion_timeout: float

    @property
    def _transport(self) -> object: ...

    def _wait_for(self, w: Waiter, timeout: float, abandon: bool = True, deadline: float = 0.0) -> None: ...

    def _flags_quietly(self) -> SystemFlag | None: ...

    def _callback(self, stream: Stream, sample: Sample) -> None: ...

    def _unsubscribe(self, stream: Stream) -> None: ...

    def _auto_reconnect(self) -> bool: ...


class Motion(MotionBase):
    """A running motion (``wait=False``): ``motion.wait(timeout)`` returns None on success and raises
    the matching :class:`~pywsg.errors.WsgError` otherwise."""

    def __init__(self, gripper: Host, call: Call[Any], final: Waiter | None, frame: Frame | None = None) -> None:
        super().__init__(call, final, frame)
        self._gripper = gripper

    def wait(self, timeout: float | None = None) -> None:
        """Wait for the final frame (``timeout`` s, default the gripper's ``motion_timeout``)."""
        if not self._checked:
            self._settle(self._gripper.motion_timeout if timeout is None else timeout)
        if self._error is not None:
            raise self._error

    def _settle(self, timeout: float) -> None:
        if self._waiting():
            assert self._final is not None
            self._gripper._wait_for(self._final, timeout, abandon=False)
            if not self._final.done:
                raise self._timed_out(timeout)
        if self._failed():
            self._fail(self._gripper._flags_quietly())


class Stream(Sink):
    """Auto-update samples: iterate (``for s in stream``, blocks), ``get(timeout)``, ``drain()``, or
    register ``callback``\\s. Keeps up to ``maxlen`` unread samples (older ones counted in ``dropped``)."""

    def __init__(self, gripper: Host, command: Command, maxlen: int = 10000,
                 callback: Callable[[Sample], None] | None = None) -> None:
        self._gripper = gripper
        self.command = command
        self._q: collections.deque[Sample] = collections.deque()
        self._cv = threading.Condition(threading.Lock())
        self._maxlen = maxlen
        self._ended = False
        self._closed = False
        self._end: BaseException | None = None
        self.received = 0
        self.dropped = 0
        self.callbacks: list[Callable[[Sample], None]] = [callback] if callback else []

    def push(self, frame: Frame) -> None:  # called on the reading thread, under the gripper's lock
        s = sample_of(frame, time.monotonic())
        if s is None:
            return
        with self._cv:
            self.received += 1
            if len(self._q) >= self._maxlen:
                self._q.popleft()
                self.dropped += 1
            self._q.append(s)
            self._cv.notify_all()
        if self.callbacks:
            self._gripper._callback(self, s)

    def revive(self) -> None:
        with self._cv:
            if not self._closed:
                self._ended = False
                self._end = None

    def end(self, exc: BaseException | None) -> None:
        with self._cv:
            self._ended = True
            self._end = exc
            self._cv.notify_all()

    def get(self, timeout: float | None = None) -> Sample:
        """The next sample; TimeoutError after ``timeout`` s; StopIteration-free: raises the end reason
        (ConnectionLostError) or ``EOFError`` when the stream was closed."""
        deadline = None if timeout is None else time.monotonic() + timeout
        with self._cv:
            while not self._q:
                if self._ended:
                    raise self._end if self._end is not None else EOFError("stream closed")
                remaining = None if deadline is None else deadline - time.monotonic()
                if remaining is not None and remaining <= 0:
                    raise TimeoutError(Status.E_TIMEOUT, int(self.command), f"no sample within {timeout} s",
                                       from_device=False)
                self._cv.wait(remaining)
            return self._q.popleft()

    def __iter__(self) -> Iterator[Sample]:
        while True:
            try:
                yield self.get()
            except EOFError:
                return

    def drain(self) -> list[Sample]:
        with self._cv:
            out = list(self._q)
            self._q.clear()
        return out

    def close(self) -> None:
        if not self._closed:
            self._closed = True
            self.end(None)
            self._gripper._unsubscribe(self)

    def __enter__(self) -> Stream:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class Callbacks:
    """Runs stream callbacks on their own thread (started with the first sample), so a callback may
    call the gripper (e.g. ``stop()``) without blocking the thread that reads."""

    def __init__(self) -> None:
        self._q: queue.SimpleQueue[tuple[Stream, Sample] | None] = queue.SimpleQueue()
        self._thread: threading.Thread | None = None

    def put(self, stream: Stream, sample: Sample) -> None:
        if self._thread is None:
            self._thread = threading.Thread(target=self._run, name="pywsg-callbacks", daemon=True)
            self._thread.start()
        self._q.put((stream, sample))

    def stop(self) -> None:
        t = self._thread
        if t is not None:
            self._q.put(None)
            if t is not threading.current_thread():
                t.join(2.0)
            self._thread = None

    def _run(self) -> None:
        while True:
            item = self._q.get()
            if item is None:
                return
            stream, sample = item
            for cb in stream.callbacks:
                try:
                    cb(sample)
                except Exception:
                    logging.getLogger("pywsg.client").exception("stream callback failed")


class Reader:
    """The background reader: a thread that runs only while auto-update streams are subscribed, so
    samples arrive while no call waits; with a reconnect policy it reconnects a lost link."""

    def __init__(self, host: Host) -> None:
        self._host = host
        self.thread: threading.Thread | None = None
        self._stop = threading.Event()

    def is_current(self) -> bool:
        """True on the reader's own thread."""
        return threading.current_thread() is self.thread

    def start(self) -> None:
        if self.thread is not None:
            return
        self._stop.clear()
        self.thread = threading.Thread(target=self._run, name="pywsg-reader", daemon=True)
        self.thread.start()

    def stop(self) -> None:
        t = self.thread
        if t is None:
            return
        self._stop.set()
        if t is not threading.current_thread():
            t.join(2.0)
        self.thread = None

    def _run(self) -> None:
        never = Waiter(-1)
        host = self._host
        try:
            while not self._stop.is_set():
                if host._transport is None:
                    if not host._auto_reconnect():
                        return
                    continue
                host._wait_for(never, READ_SLICE, abandon=False)
        finally:
            if self.thread is threading.current_thread():
                self.thread = None
