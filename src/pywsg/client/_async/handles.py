"""What the asyncio driver's calls hand back: :class:`AsyncMotion` (a running motion,
``wait=False``) and :class:`AsyncStream` (auto-update samples), and the waiter with a future they wait on."""

from __future__ import annotations

import asyncio
import collections
import time
from collections.abc import Callable
from typing import Any, Protocol

from ...errors import TimeoutError
from ...protocol import Command, Frame, Status, SystemFlag
from ..calls import Call
from ..core import sample_of
from ..demux import Sink, Waiter
from ..motion import MotionBase
from ..types import Sample
from .transport import WAIT_TIMEOUT


class Host(Protocol):
    """What the handles need from the asyncio shell (:class:`~pywsg.client.AsyncGripper` implements it),
    so the shell imports the handles and not the other way round."""

    motion_timeout: float

    async def _flags_quietly(self) -> SystemFlag | None: ...

    async def _unsubscribe(self, stream: AsyncStream) -> None: ...


class AWaiter(Waiter):
    """A waiter with a future; ``deadline`` (loop time) is watched by the gripper's one timer."""

    __slots__ = ("deadline", "fut", "timeout")

    def __init__(self, command_id: int, loop: asyncio.AbstractEventLoop, final: Waiter | None = None) -> None:
        # Waiter.__init__ inlined: this runs for every request
        self.command_id = command_id
        self.frame = None
        self.error = None
        self.done = False
        self.ghost_until = 0.0
        self.robbed = False
        self.final = final
        self.deadline = 0.0
        self.timeout = 0.0
        self.fut: asyncio.Future[None] = loop.create_future()

    def _wake(self) -> None:
        if not self.fut.done():
            self.fut.set_result(None)



class AsyncMotion(MotionBase):
    """A running motion (``wait=False``): ``await motion`` or ``await motion.wait(timeout)``.

    ``wait()`` returns None when the motion ended with E_SUCCESS and raises the matching
    :class:`~pywsg.errors.WsgError` otherwise (e.g. ``AbortedError`` after ``stop()``).
    """

    _final: AWaiter | None

    def __init__(self, gripper: Host, call: Call[Any], final: AWaiter | None,
                 frame: Frame | None = None) -> None:
        super().__init__(call, final, frame)
        self._gripper = gripper

    async def wait(self, timeout: float | None = None) -> None:
        """Wait for the final frame (``timeout`` s, default the gripper's ``motion_timeout``)."""
        if not self._checked:
            await self._settle(self._gripper.motion_timeout if timeout is None else timeout)
        if self._error is not None:
            raise self._error

    async def _settle(self, timeout: float) -> None:
        if self._waiting():
            assert self._final is not None
            try:
                await asyncio.wait_for(asyncio.shield(self._final.fut), timeout)
            except WAIT_TIMEOUT:  # Python 3.10: asyncio.TimeoutError is not the builtin
                raise self._timed_out(timeout) from None
        if self._failed():
            self._fail(await self._gripper._flags_quietly())

    def __await__(self) -> Any:
        return self.wait().__await__()


class AsyncStream(Sink):
    """Auto-update samples as an async iterator: ``async for sample in stream``.

    Keeps up to ``maxlen`` samples not yet consumed (older ones are counted in ``dropped``).
    ``await stream.close()`` (or ``async with``) ends the subscription.
    """

    def __init__(self, gripper: Host, command: Command, maxlen: int = 10000) -> None:
        self._gripper = gripper
        self.command = command
        self._q: collections.deque[Sample] = collections.deque()
        self._maxlen = maxlen
        self._waiter: asyncio.Future[None] | None = None
        self._end: BaseException | None = None
        self._ended = False
        self._closed = False
        self.received = 0
        self.dropped = 0
        self.callbacks: list[Callable[[Sample], None]] = []

    def push(self, frame: Frame) -> None:
        s = sample_of(frame, time.monotonic())
        if s is None:
            return
        self.received += 1
        for cb in self.callbacks:
            cb(s)
        if len(self._q) >= self._maxlen:
            self._q.popleft()
            self.dropped += 1
        self._q.append(s)
        w = self._waiter
        if w is not None and not w.done():
            w.set_result(None)

    def revive(self) -> None:
        if not self._closed:
            self._ended = False
            self._end = None

    def end(self, exc: BaseException | None) -> None:
        self._ended = True
        self._end = exc
        w = self._waiter
        if w is not None and not w.done():
            w.set_result(None)

    def __aiter__(self) -> AsyncStream:
        return self

    async def __anext__(self) -> Sample:
        while not self._q:
            if self._ended:
                if self._end is not None:
                    raise self._end
                raise StopAsyncIteration
            self._waiter = asyncio.get_running_loop().create_future()
            try:
                await self._waiter
            finally:
                self._waiter = None
        return self._q.popleft()

    async def get(self, timeout: float | None = None) -> Sample:
        """The next sample (waits at most ``timeout`` s; TimeoutError after that)."""
        try:
            return await asyncio.wait_for(self.__anext__(), timeout)
        except WAIT_TIMEOUT:  # Python 3.10: asyncio.TimeoutError is not the builtin
            raise TimeoutError(Status.E_TIMEOUT, int(self.command), f"no sample within {timeout} s",
                               from_device=False) from None

    def drain(self) -> list[Sample]:
        """All samples received and not yet consumed."""
        out = list(self._q)
        self._q.clear()
        return out

    async def close(self) -> None:
        if not self._closed:
            self._closed = True
            self.end(None)
            await self._gripper._unsubscribe(self)

    async def __aenter__(self) -> AsyncStream:
        return self

    async def __aexit__(self, *exc: object) -> None:
        await self.close()

