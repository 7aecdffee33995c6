"""``AsyncGripper``: the asyncio driver."""

from __future__ import annotations

import asyncio
import logging
import time
from collections.abc import AsyncIterator, Callable
from types import TracebackType
from typing import Any, TypeVar

from ...errors import ConnectionLostError
from ...protocol import Frame, FrameParser, SystemFlag, parse_datagram
from .. import lifetime
from ..calls import Call
from ..commlog import RX, TX, frame_log
from ..core import DEFAULT_MOTION_TIMEOUT, DEFAULT_TIMEOUT, decode_success, frame_from, stream_id
from ..demux import Waiter
from ..reconnect import ReconnectPolicy
from ..types import Sample, State
from ..url import Endpoint
from .commands import AsyncCommands, AsyncFinger
from .handles import AsyncMotion, AsyncStream, AWaiter
from .lifecycle import AsyncLifecycle
from .transport import WAIT_TIMEOUT, AsyncTransport, SerialTransport, TcpTransport, UdpTransport

__all__ = ["AsyncFinger", "AsyncGripper", "AsyncMotion", "AsyncStream", "ReconnectPolicy"]

T = TypeVar("T")

_COMPACT_AT = 256  # timed waiters kept before the finished ones are swept out


class AsyncGripper(AsyncCommands, AsyncLifecycle):
    """asyncio driver for a WSG gripper. Open with ``await AsyncGripper.open(url)`` or
    ``async with AsyncGripper(url) as g``.

    ``timeout``: s to wait for an immediate reply; ``motion_timeout``: s to wait for a motion's
    final frame; ``reconnect``: True or a :class:`ReconnectPolicy` to reconnect automatically after
    a dropped connection (subscriptions are restored; a FAST STOP found is reported through
    ``on_reconnect`` and the log, never acknowledged). ``on_reconnect(flags)`` is called with the
    system flags found after every reconnection, ``on_connection_lost(exc)`` when the connection
    drops; both may also be set as attributes later.
    """

    def __init__(self, url: str | Endpoint, *, timeout: float = DEFAULT_TIMEOUT,
                 motion_timeout: float = DEFAULT_MOTION_TIMEOUT, connect_timeout: float = 5.0,
                 reconnect: bool | ReconnectPolicy = False, verify_checksum: bool = True,
                 on_reconnect: Callable[[SystemFlag], None] | None = None,
                 on_connection_lost: Callable[[BaseException | None], None] | None = None) -> None:
        self._setup(url, timeout, motion_timeout, connect_timeout, reconnect, verify_checksum, on_reconnect,
                    on_connection_lost)
        self._loop: asyncio.AbstractEventLoop | None = None
        self._transport: AsyncTransport | None = None
        self._reconnect_task: asyncio.Task[bool] | None = None
        self._dropped: AsyncTransport | None = None  # the transport _drop closed last (see _wait_closed)
        # Timeouts: one timer per gripper at the earliest deadline of the calls in _timed, instead
        # of a timer handle created and cancelled per call (a heap push and a cancelled-timer sweep).
        self._timed: list[AWaiter] = []
        self._timer: asyncio.TimerHandle | None = None
        self._timer_at = 0.0
        self._compact_at = _COMPACT_AT

    # ------------------------------------------------------------------ connection
    @classmethod
    async def open(cls, url: str | Endpoint, **kwargs: Any) -> AsyncGripper:
        """Connect and return the driver."""
        g = cls(url, **kwargs)
        await g.connect()
        return g

    async def connect(self) -> None:
        """Open the transport named by the URL."""
        if self._transport is not None:
            return
        self._loop = asyncio.get_running_loop()
        self._closing = False
        self._dropped = None
        self._parser = FrameParser(self.verify_checksum)
        ep = self.endpoint
        try:
            if ep.scheme == "tcp":
                self._transport = await TcpTransport.connect(ep, self._on_data, self._on_lost, self.connect_timeout)
            elif ep.scheme == "udp":
                self._transport = await UdpTransport.connect(ep, self._on_datagram, self._on_lost,
                                                             self.connect_timeout)
            elif ep.scheme == "can":
                from .can_transport import CanTransport

                self._transport = await CanTransport.connect(ep, self._on_data, self._on_lost, self.connect_timeout)
            else:
                self._transport = await SerialTransport.connect(ep, self._on_data, self._on_lost,
                                                                self.connect_timeout)
        except OSError as exc:
            raise ConnectionLostError(f"cannot connect to {ep}: {exc or type(exc).__name__}") from exc
        except WAIT_TIMEOUT as exc:  # Python 3.10: asyncio.TimeoutError is not the builtin TimeoutError
            raise ConnectionLostError(f"cannot connect to {ep}: {exc or type(exc).__name__}") from exc
        self._connected()

    async def close(self) -> None:
        """Announce the disconnect (TCP: 07h, so the gripper does not FAST STOP), then close.
        A gripper still open when the interpreter exits is announced then (see docs/driver.md)."""
        self._closing = True
        lifetime.closed(self)
        if self._reconnect_task is not None:
            self._reconnect_task.cancel()
            self._reconnect_task = None
        if self._transport is None:
            return
        await self._announce_disconnect()
        self._drop(ConnectionLostError("connection closed by the client"), end_streams=True, forget=True)
        await self._wait_closed()  # closed when close() returns: a new connection right after is not refused

    def _close_at_exit(self) -> None:
        """No event loop runs any more: write 07h on the socket directly, without waiting for the reply."""
        t, self._transport = getattr(self, "_transport", None), None
        if t is None:
            return
        self._closing = True
        if self._announces:
            lifetime.announce_on_socket(t.raw_socket())
        try:
            t.close()
        except RuntimeError:  # the loop is closed: the socket goes with the process
            pass

    def _guard(self) -> None:
        # only the socket: the transport's protocol calls back into the gripper and would keep it alive
        t = self._transport
        assert t is not None
        lifetime.guard(self, t.raw_socket() if self._announces else None,
                       "await close() or use 'async with AsyncGripper(...) as g'")

    def _drop(self, exc: ConnectionLostError, end_streams: bool, forget: bool = False) -> None:
        """Close the transport and fail the waiting calls. ``end_streams``: the streams end with
        ``exc`` (kept for ``reconnect()`` unless ``forget``)."""
        lifetime.unguard(self)
        t, self._transport = self._transport, None
        if t is not None:
            t.close()
            self._dropped = t
        if self._timer is not None:
            self._timer.cancel()
            self._timer = None
        self._timed.clear()
        self._demux.fail_all(lambda cid: ConnectionLostError(exc.detail, cid))
        if end_streams:
            for cmd, streams in list(self._streams.items()):
                for st in streams:
                    st.end(None if forget else ConnectionLostError(exc.detail, int(cmd)))
        if forget:
            for cmd, streams in list(self._streams.items()):
                for st in streams:
                    self._demux.remove_stream(cmd, st)
            self._streams.clear()
            self._subs.clear()

    # lifecycle hooks (see _async/lifecycle.py)
    async def _pause(self, delay: float) -> None:
        await asyncio.sleep(delay)

    async def _wait_closed(self) -> None:
        # Close the old connection before a new one is made: asyncio closes a socket one loop turn
        # after transport.close(). On Python 3.12 and 3.13 the new connection was made within that
        # turn (0.6 ms after the 07h reply on loopback, against 2.8 ms on 3.11), so its SYN overtook
        # the old connection's FIN, and a gripper that serves one TCP client at a time (the sim
        # likewise, docs/fidelity.md) still counted the old one as the controller: every command of
        # the new connection got E_ACCESS_DENIED.
        t, self._dropped = self._dropped, None
        if t is not None:
            await t.wait_closed(min(self.connect_timeout, 1.0))

    def _forget_final(self, final: Waiter) -> None:
        self._demux.forget_final(final)

    def _resume_streams(self) -> None:
        pass  # the streams are fed by the event loop's reading

    def _streams_idle(self) -> None:
        pass

    def _start_reconnecting(self) -> None:
        if self._reconnect_task is None and self._loop is not None:
            self._reconnect_task = self._loop.create_task(self._auto_reconnect())
            self._reconnect_task.add_done_callback(self._reconnect_done)

    async def __aenter__(self) -> AsyncGripper:
        await self.connect()
        return self

    async def __aexit__(self, et: type[BaseException] | None, ev: BaseException | None,
                        tb: TracebackType | None) -> None:
        await self.close()

    # ------------------------------------------------------------------ bytes in
    def _on_data(self, data: memoryview) -> None:
        parser = self._parser
        if not parser.buffered:
            frame = frame_from(bytes(data), parser.verify_checksum, parser.max_payload)
            if frame is not None:
                comm = self._comm
                if comm.hook is not None or frame_log.isEnabledFor(logging.DEBUG):
                    comm.frame(RX, frame)
                self._demux.feed(frame)
                return
        for ev in parser.feed(data):
            self._on_event(ev)

    def _on_datagram(self, data: bytes) -> None:
        for ev in parse_datagram(data, self.verify_checksum):
            self._on_event(ev)

    def _on_lost(self, exc: BaseException | None) -> None:
        if self._transport is not None:  # not dropped already
            self._lost(exc)

    def _reconnect_done(self, _t: asyncio.Task[bool]) -> None:
        self._reconnect_task = None

    # ------------------------------------------------------------------ requests
    def _transport_or_raise(self, cid: int) -> AsyncTransport:
        t = self._transport
        if t is None:
            raise self._not_connected(cid)
        return t

    async def _await_reconnect(self) -> None:
        task = self._reconnect_task
        if task is not None and self._transport is None:
            try:
                await asyncio.wait_for(asyncio.shield(task), self.connect_timeout)
            except WAIT_TIMEOUT:
                pass
            except asyncio.CancelledError:
                pass

    def _send(self, call: Call[Any], timeout: float | None) -> tuple[AWaiter, AWaiter | None]:
        """Send one request; return the waiter of its first reply (timed) and that of a pending final."""
        t = self._transport_or_raise(call.command_id)
        loop = self._loop
        assert loop is not None
        cid = call.command_id
        final = AWaiter(cid, loop) if call.pending else None
        w = AWaiter(cid, loop, final)
        self._demux.expect(w)
        wire = call.wire
        if call.auto_read and self._subs:
            wire = self._read_wire(call)
        comm = self._comm
        if comm.hook is not None or frame_log.isEnabledFor(logging.DEBUG):
            comm.frame(TX, Frame(cid, wire[6:-2]))
        # self._time(w, loop, timeout) inlined: this runs for every request
        if timeout is None:
            timeout = self.timeout
        w.deadline = d = time.monotonic() + timeout
        w.timeout = timeout
        timed = self._timed
        if len(timed) >= self._compact_at:
            self._compact()
        timed.append(w)
        if self._timer is None or d < self._timer_at:
            self._arm(loop, d)
        t.write(wire)
        return w, final

    async def _exchange(self, call: Call[Any], timeout: float | None) -> tuple[Frame, AWaiter | None]:
        """Send one request; return its first reply and the waiter of a pending final."""
        if self._transport is None:
            await self._await_reconnect()
        w, final = self._send(call, timeout)
        return await self._reply(w), final

    # -- timeouts
    def _time(self, w: AWaiter, loop: asyncio.AbstractEventLoop, timeout: float) -> None:
        """Fail ``w`` with TimeoutError if it is not done ``timeout`` s from now."""
        # time.monotonic() is the loop's clock (asyncio's and uvloop's), without a method call
        w.deadline = d = time.monotonic() + timeout
        w.timeout = timeout
        timed = self._timed
        if len(timed) >= self._compact_at:
            self._compact()
        timed.append(w)
        if self._timer is None or d < self._timer_at:
            self._arm(loop, d)

    def _compact(self) -> None:
        """Sweep finished waiters out of ``_timed`` (amortised: the threshold follows the live count)."""
        timed = self._timed
        timed[:] = [x for x in timed if not x.done]
        self._compact_at = max(_COMPACT_AT, 2 * len(timed))

    def _arm(self, loop: asyncio.AbstractEventLoop, when: float) -> None:
        if self._timer is not None:
            self._timer.cancel()
        self._timer = loop.call_at(when, self._on_timer)
        self._timer_at = when

    def _on_timer(self) -> None:
        self._timer = None
        loop = self._loop
        assert loop is not None
        now = time.monotonic()
        keep: list[AWaiter] = []
        for w in self._timed:
            if w.done:
                continue
            if w.deadline <= now:
                self._expire(w, w.timeout)
            else:
                keep.append(w)
        self._timed = keep
        if keep:
            self._arm(loop, min(w.deadline for w in keep))

    async def _reply(self, w: AWaiter) -> Frame:
        try:
            await w.fut
        except asyncio.CancelledError:
            self._demux.abandon(w)
            raise
        if w.error is not None:
            raise w.error
        return w.frame  # type: ignore[return-value]  # set when done without error

    async def _final_frame(self, w: AWaiter, timeout: float) -> Frame:
        loop = self._loop
        assert loop is not None
        self._time(w, loop, timeout)
        return await self._reply(w)

    async def _run(self, call: Call[T], timeout: float | None = None) -> T:
        """An immediate command: the decoded result, or the matching WsgError."""
        if self._transport is None:
            await self._await_reconnect()
        w, _ = self._send(call, timeout)
        try:
            await w.fut
        except asyncio.CancelledError:
            self._demux.abandon(w)
            raise
        if w.error is not None:
            raise w.error
        frame = w.frame
        assert frame is not None
        p = frame.payload
        if len(p) >= 2 and p[0] == 0 and p[1] == 0:  # E_SUCCESS
            memo = call.memo
            if memo is not None:  # decode_success's first step, inline
                r = memo.get(p)
                if r is not None:
                    return r
            return decode_success(call, frame)
        return await self._result(call, frame)

    async def state(self) -> State:
        """Width, speed, force, gripper state, flags and temperature, read with 6 pipelined requests."""
        w, s, f, gs, fl, te = await asyncio.gather(
            self.width(), self.speed(), self.force(), self.gripper_state(), self.system_state(),
            self.temperature())
        return State(w, s, f, gs, fl, te)

    # ------------------------------------------------------------------ streams
    async def subscribe(self, what: str | int, period: float = 0.01, change_only: bool = False,
                        maxlen: int = 10000) -> AsyncStream:
        """Auto-update stream of ``what`` ("system_state", "gripper_state", "width", "speed", "force"
        or the command ID), one packet at most every ``period`` s (>= 0.01), only on change if
        ``change_only``. The first sample is the current value."""
        return await self._open_stream(AsyncStream(self, stream_id(what), maxlen), period, change_only)

    async def stream(self, what: str | int, period: float = 0.01,
                     change_only: bool = False) -> AsyncIterator[Sample]:
        """``async for s in g.stream("width")``: subscribe, yield samples, unsubscribe at the end."""
        s = await self.subscribe(what, period, change_only)
        try:
            async for sample in s:
                yield sample
        finally:
            await s.close()

