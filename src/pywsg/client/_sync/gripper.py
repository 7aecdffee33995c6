"""``Gripper``: the blocking driver, for scripts and notebooks (no event loop needed).

I/O design: plain blocking sockets. The thread that waits for a reply reads the socket itself
(no thread hop on the common path); when several threads wait, one reads and hands frames to the
others. A background reader thread runs only while auto-update streams are subscribed, and stream
callbacks run on their own thread, so a callback may call the gripper (e.g. ``stop()``).
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from types import TracebackType
from typing import Any, TypeVar

from ...errors import ConnectionLostError
from ...protocol import Frame, FrameParser, SystemFlag, parse_datagram
from .. import calls, lifetime
from ..calls import Call
from ..commlog import RX, TX, frame_log
from ..core import DEFAULT_MOTION_TIMEOUT, DEFAULT_TIMEOUT, decode_success, frame_from, stream_id
from ..demux import Waiter
from ..reconnect import ReconnectPolicy
from ..types import Sample, State
from ..url import Endpoint
from .connect import open_sync
from .generated_commands import Commands, Finger
from .generated_lifecycle import Lifecycle
from .handles import Callbacks, Motion, Reader, Stream
from .transport import SyncTransport

__all__ = ["Finger", "Gripper", "Motion", "ReconnectPolicy", "Stream"]

T = TypeVar("T")

_DEBUG = logging.DEBUG


class Gripper(Commands, Lifecycle):
    """Blocking driver for a WSG gripper: ``with Gripper("tcp://192.168.1.20") as g: g.home()``.

    Same methods and arguments as :class:`~pywsg.client.AsyncGripper`, without ``await``.
    ``connect=False`` defers opening the connection to ``connect()`` / ``with``.
    ``on_reconnect(flags)`` and ``on_connection_lost(exc)``: as for ``AsyncGripper`` (also attributes).
    """

    def __init__(self, url: str | Endpoint, *, timeout: float = DEFAULT_TIMEOUT,
                 motion_timeout: float = DEFAULT_MOTION_TIMEOUT, connect_timeout: float = 5.0,
                 reconnect: bool | ReconnectPolicy = False, verify_checksum: bool = True,
                 connect: bool = True, on_reconnect: Callable[[SystemFlag], None] | None = None,
                 on_connection_lost: Callable[[BaseException | None], None] | None = None) -> None:
        self._setup(url, timeout, motion_timeout, connect_timeout, reconnect, verify_checksum, on_reconnect,
                    on_connection_lost)
        self._lock = threading.Lock()
        self._cv = threading.Condition(self._lock)  # hot paths enter self._lock directly (C-level)
        self._state_lock = self._lock
        self._send_lock = threading.Lock()
        self._reading = False
        self._sleepers = 0  # threads waiting on self._cv
        self._transport: SyncTransport | None = None
        self._partial = False  # the parser holds part of a frame (kept by _feed, the parser's only feeder)
        self._reader = Reader(self)   # the background reader while streams run
        self._callbacks = Callbacks()
        if connect:
            self.connect()

    # ------------------------------------------------------------------ connection
    @classmethod
    def open(cls, url: str | Endpoint, **kwargs: Any) -> Gripper:
        return cls(url, **kwargs)

    def connect(self) -> None:
        if self._transport is not None:
            return
        try:
            t = open_sync(self.endpoint, self.connect_timeout)
        except OSError as exc:
            raise ConnectionLostError(f"cannot connect to {self.endpoint}: {exc}") from exc
        with self._lock:
            self._parser = FrameParser(self.verify_checksum)
            self._partial = False
            self._transport = t
            self._closing = False
        self._connected()

    def close(self) -> None:
        """Announce the disconnect (TCP: 07h, so the gripper does not FAST STOP), then close.
        A gripper still open when the interpreter exits is closed this way too (see docs/driver.md)."""
        self._closing = True
        lifetime.closed(self)
        self._announce_disconnect()
        self._reader.stop()
        self._drop(ConnectionLostError("connection closed by the client"), end_streams=True, forget=True)
        self._callbacks.stop()

    def _close_at_exit(self) -> None:
        if self._transport is not None:
            self.close()

    def _guard(self) -> None:
        t = self._transport
        assert t is not None
        lifetime.guard(self, getattr(t, "sock", None) if self._announces else None,
                       "call close() or use 'with Gripper(...) as g'", t.close)

    def _drop(self, exc: ConnectionLostError, end_streams: bool, forget: bool = False) -> None:
        """Close the transport and fail the waiting calls. ``end_streams``: the streams end with
        ``exc`` (kept for ``reconnect()`` unless ``forget``)."""
        lifetime.unguard(self)
        with self._lock:
            t, self._transport = self._transport, None
            self._demux.fail_all(lambda cid: ConnectionLostError(exc.detail, cid))
            streams = [(cmd, st) for cmd, lst in self._streams.items() for st in lst]
            if forget:
                for cmd, st in streams:
                    self._demux.remove_stream(cmd, st)
                self._streams.clear()
                self._subs.clear()
            self._cv.notify_all()
        if end_streams:
            for cmd, st in streams:
                st.end(None if forget else ConnectionLostError(exc.detail, int(cmd)))
        if t is not None:
            t.close()

    # lifecycle hooks (see _async/lifecycle.py)
    def _pause(self, delay: float) -> None:
        time.sleep(delay)

    def _wait_closed(self) -> None:
        pass  # a blocking socket is closed when close() returns

    def _forget_final(self, final: Waiter) -> None:
        with self._lock:
            self._demux.forget_final(final)

    def _resume_streams(self) -> None:
        if self._streams and not self._reader.is_current():
            self._reader.start()

    def _streams_idle(self) -> None:
        self._reader.stop()

    def _start_reconnecting(self) -> None:
        pass  # on demand: by the next call (_transport_or_raise) or the stream reader

    def __enter__(self) -> Gripper:
        self.connect()
        return self

    def __exit__(self, et: type[BaseException] | None, ev: BaseException | None, tb: TracebackType | None) -> None:
        self.close()

    # ------------------------------------------------------------------ reading
    def _feed(self, data: bytes) -> None:
        """Route received bytes (call with self._cv held)."""
        parser = self._parser
        if not self._partial:
            frame = frame_from(data, parser.verify_checksum, parser.max_payload)
            if frame is not None:
                if self._comm.active:
                    self._comm.frame(RX, frame)
                self._demux.feed(frame)
                return
        t = self._transport
        if t is not None and t.datagram:
            events = parse_datagram(data, self.verify_checksum)
        else:
            events = parser.feed(data)
            self._partial = parser.buffered > 0
        for ev in events:
            self._on_event(ev)

    def _wait_for(self, w: Waiter, timeout: float, abandon: bool = True, deadline: float = 0.0) -> None:
        """Block until ``w`` is done or ``timeout`` s passed (then, with ``abandon``, fail it with
        TimeoutError and leave a ghost for its late reply). Reads the socket itself when nobody else does.
        ``deadline``: the monotonic time the wait ends, when it began earlier."""
        if not deadline:
            deadline = time.monotonic() + timeout
        with self._lock:
            if w.done:
                return
            if self._reading and not self._sleep(w, deadline, timeout, abandon):
                return
            self._reading = True
        self._read(w, timeout, abandon, True, deadline)

    def _read(self, w: Waiter, timeout: float, abandon: bool, logged: bool = True, deadline: float = 0.0) -> None:
        """Read the transport until ``w`` is done or ``timeout`` s passed; the caller has set
        ``_reading``. The reading is given up in the same critical section that completes ``w``.
        ``logged``: False when the caller found the communication log idle (then a whole frame skips it)."""
        if deadline:
            remaining = deadline - time.monotonic()
        else:
            deadline = time.monotonic() + timeout
            remaining = timeout
        lock = self._lock
        try:
            while True:
                t = self._transport
                if t is None:
                    break
                if remaining <= 0:
                    if abandon:
                        with lock:
                            self._expire(w, timeout)
                    break
                try:
                    data = t.recv(remaining)
                except OSError as exc:
                    with lock:
                        self._reading = False
                        self._wake_sleepers()
                    self._lost(exc)
                    return
                if data:
                    with lock:
                        if self._partial:
                            self._feed(data)
                        else:
                            parser = self._parser
                            frame = frame_from(data, parser.verify_checksum, parser.max_payload)
                            if frame is None:
                                self._feed(data)
                            else:  # one whole frame: the usual reply
                                if logged and self._comm.active:
                                    self._comm.frame(RX, frame)
                                self._demux.feed(frame)
                        if w.done:
                            self._reading = False
                            if self._sleepers:
                                self._cv.notify_all()
                            return
                        self._wake_sleepers()
                elif w.done:  # completed by a failure (e.g. the connection dropped)
                    break
                remaining = deadline - time.monotonic()
        except BaseException:
            with lock:
                self._reading = False
                self._wake_sleepers()
            raise
        with lock:
            self._reading = False
            self._wake_sleepers()

    def _wake_sleepers(self) -> None:
        if self._sleepers:
            self._cv.notify_all()

    def _sleep(self, w: Waiter, deadline: float, timeout: float, abandon: bool) -> bool:
        """Another thread reads: sleep until ``w`` is done (False) or the reading is free (True).
        Call with the lock held."""
        while not w.done:
            if not self._reading:
                return True
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                if abandon:
                    self._expire(w, timeout)
                return False
            self._sleepers += 1
            try:
                self._cv.wait(remaining)
            finally:
                self._sleepers -= 1
        return False

    # ------------------------------------------------------------------ requests
    def _transport_or_raise(self, cid: int) -> SyncTransport:
        t = self._transport
        if (t is None and self.policy is not None and not self._closing and self._reader.thread is None
                and not self._backoff.gave_up):
            self._auto_reconnect()
            t = self._transport
        if t is None and self._reader.thread is not None and self.policy is not None:
            deadline = time.monotonic() + self.connect_timeout
            while self._transport is None and time.monotonic() < deadline and not self._closing:
                time.sleep(0.01)
            t = self._transport
        if t is None:
            raise self._not_connected(cid)
        return t

    def _send(self, t: SyncTransport, waiters: list[Waiter], wires: list[bytes]) -> None:
        if self._comm.active:
            for wire in wires:
                self._comm.frame(TX, Frame(wire[3], wire[6:-2]))
        try:
            with self._send_lock:  # registered in the order of sending (FIFO per ID)
                with self._lock:
                    for w in waiters:
                        self._demux.expect(w)
                if len(wires) == 1:
                    t.send(wires[0])
                else:
                    t.send_frames(wires)
        except OSError as exc:
            self._lost(exc)

    def _exchange(self, call: Call[Any], timeout: float | None) -> tuple[Frame, Waiter | None]:
        t = self._transport
        if t is None:
            t = self._transport_or_raise(call.command_id)
        cid = call.command_id
        final = Waiter(cid) if call.pending else None
        w = Waiter(cid, final)
        wire = self._read_wire(call) if call.auto_read and self._subs else call.wire
        if timeout is None:
            timeout = self.timeout
        comm = self._comm
        logged = comm.hook is not None or frame_log.isEnabledFor(logging.DEBUG)
        if logged:
            comm.frame(TX, Frame(wire[3], wire[6:-2]))
        reader = False
        try:
            # registered under the send lock: replies of one ID come back in the order of sending
            with self._send_lock:
                with self._lock:
                    self._demux.expect(w)
                    reader = not self._reading  # nobody reads: this thread will, no second lock round
                    if reader:
                        self._reading = True
                t.send(wire)
        except OSError as exc:
            if reader:
                with self._lock:
                    self._reading = False
                    self._wake_sleepers()
            self._lost(exc)
            reader = False
        except BaseException:
            if reader:
                with self._lock:
                    self._reading = False
                    self._wake_sleepers()
            raise
        if reader:
            self._read(w, timeout, True, logged)
        else:
            self._wait_for(w, timeout)
        if w.error is not None:
            raise w.error
        assert w.frame is not None
        return w.frame, final

    def _run(self, call: Call[T], timeout: float | None = None) -> T:
        t = self._transport
        if (t is None or call.pending or self._partial or (call.auto_read and self._subs)
                or self._comm.hook is not None or frame_log.isEnabledFor(_DEBUG)):
            frame, _ = self._exchange(call, timeout)
        else:
            frame = self._exchange_immediate(t, call, self.timeout if timeout is None else timeout)
        p = frame.payload
        if len(p) >= 2 and p[0] == 0 and p[1] == 0:  # E_SUCCESS
            memo = call.memo
            if memo is not None:  # decode_success's first step, inline
                r = memo.get(p)
                if r is not None:
                    return r
            return decode_success(call, frame)
        return self._result(call, frame)

    def _exchange_immediate(self, t: SyncTransport, call: Call[Any], timeout: float) -> Frame:
        """:meth:`_exchange` flattened for the common call: an immediate command, no communication
        log, no partial frame buffered.

        When nobody else reads and nothing else is expected on this ID, the call waits without a
        :class:`Waiter`: the first frame of its ID to arrive is its reply (calls of other threads
        on the same ID were sent later and queue behind it). Anything else - another frame, several
        frames, a bad CRC, a timeout, an error - first registers the waiter at the head of its ID's
        queue (:meth:`Demux.expect_first`), then continues the general way with the same deadline.
        """
        deadline = time.monotonic() + timeout
        cid = call.command_id
        demux = self._demux
        lock = self._lock
        w: Waiter | None = None
        reader = False
        try:
            with self._send_lock:  # registered in the order of sending (FIFO per ID)
                with lock:
                    reader = not self._reading
                    if reader:
                        self._reading = True
                    if not reader or not demux.alone(cid):
                        w = Waiter(cid)
                        demux.expect(w)
                t.send(call.wire)
            if reader:
                data = t.recv(timeout)
                with lock:
                    if w is None:
                        if data and not self._partial:
                            frame = frame_from(data, self._parser.verify_checksum, self._parser.max_payload)
                            if frame is not None and frame.command_id == cid:  # the reply
                                self._reading = False
                                if self._sleepers:
                                    self._cv.notify_all()
                                return frame
                        w = Waiter(cid)
                        demux.expect_first(w)
                    if data:
                        self._feed(data)
                        if w.done:  # the reply (or a bad-CRC failure): give the reading up
                            self._reading = False
                            reader = False
                            self._wake_sleepers()
        except OSError as exc:
            with lock:
                if w is None:
                    w = Waiter(cid)
                    demux.expect_first(w)
                if reader:
                    self._reading = False
                    self._wake_sleepers()
            self._lost(exc)
            reader = False
        except BaseException:
            with lock:
                if w is None:  # stays queued: it swallows the reply when it comes
                    demux.expect_first(Waiter(cid))
                if reader:
                    self._reading = False
                    self._wake_sleepers()
            raise
        assert w is not None
        if not w.done:
            if reader:
                self._read(w, timeout, True, True, deadline)
            else:
                self._wait_for(w, timeout, True, deadline)
        if w.error is not None:
            raise w.error
        assert w.frame is not None
        return w.frame

    def _final_frame(self, final: Waiter, timeout: float) -> Frame:
        self._wait_for(final, timeout)
        if final.error is not None:
            raise final.error
        assert final.frame is not None
        return final.frame

    def state(self) -> State:
        """Width, speed, force, gripper state, flags and temperature, read with 6 pipelined requests."""
        cs: list[Call[Any]] = [calls.width(), calls.speed(), calls.force(), calls.gripper_state(),
                               calls.system_state(), calls.temperature()]
        t = self._transport_or_raise(cs[0].command_id)
        ws = [Waiter(c.command_id) for c in cs]
        self._send(t, ws, [self._read_wire(c) if self._subs else c.wire for c in cs])
        out: list[Any] = []
        for c, w in zip(cs, ws, strict=True):
            self._wait_for(w, self.timeout)
            if w.error is not None:
                raise w.error
            assert w.frame is not None
            out.append(self._result(c, w.frame))
        return State(*out)

    # ------------------------------------------------------------------ streams
    def subscribe(self, what: str | int, period: float = 0.01, change_only: bool = False, *,
                  callback: Callable[[Sample], None] | None = None, maxlen: int = 10000) -> Stream:
        """Auto-update stream of ``what`` ("system_state", "gripper_state", "width", "speed", "force"
        or the command ID), at most one packet every ``period`` s (>= 0.01), only on change if
        ``change_only``. ``callback(sample)`` runs on a callback thread and may call the gripper."""
        return self._open_stream(Stream(self, stream_id(what), maxlen, callback), period, change_only)

    def _callback(self, stream: Stream, sample: Sample) -> None:
        self._callbacks.put(stream, sample)

