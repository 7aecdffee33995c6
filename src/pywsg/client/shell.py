"""What the asyncio and the blocking shell share, written once: the constructor's arguments, the URL,
the reconnect policy and its back-off, the bookkeeping of the connection's lifecycle (connected,
lost, reconnected) and the routing of a parsed frame. No I/O here: each shell supplies the hooks
(``_drop``, ``_start_reconnecting``) and does its own sending, reading, waiting and sleeping.

The lifecycle *flows* that wait on the gripper (reconnect, the give-up loop, a motion's first reply,
the error report's flags, ``request()``) are written once in ``_async/lifecycle.py`` and generated for
the blocking shell by ``scripts/unasync_client.py``, as the command methods are.
"""

from __future__ import annotations

import contextlib
import logging
import time
from collections.abc import Callable
from typing import Any, Generic, TypeVar

from ..errors import ConnectionLostError, TimeoutError
from ..protocol import ChecksumMismatch, Command, Frame, FrameParser, GarbageSkipped, ParseError, Status, SystemFlag
from . import calls, lifetime
from .calls import Call
from .commlog import RX, CommHook, CommLog
from .core import bad_checksum
from .demux import Demux, Sink, Waiter
from .reconnect import Backoff, ReconnectPolicy
from .url import Endpoint, parse_url

log = logging.getLogger("pywsg.client")


S = TypeVar("S", bound=Sink)  # the shell's stream type


class ShellBase(Generic[S]):
    """State and sans-IO steps of a driver shell; ``S`` is the shell's stream type."""

    _transport: Any  # the shell's transport, None while not connected

    def _setup(self, url: str | Endpoint, timeout: float, motion_timeout: float, connect_timeout: float,
               reconnect: bool | ReconnectPolicy, verify_checksum: bool,
               on_reconnect: Callable[[SystemFlag], None] | None,
               on_connection_lost: Callable[[BaseException | None], None] | None) -> None:
        """The constructor's common part (the shells' ``__init__`` documents the arguments)."""
        self.endpoint = url if isinstance(url, Endpoint) else parse_url(url)
        self.timeout = timeout
        self.motion_timeout = motion_timeout
        self.connect_timeout = connect_timeout
        self.policy: ReconnectPolicy | None = (ReconnectPolicy() if reconnect is True else reconnect or None)
        self._backoff = Backoff(self.policy or ReconnectPolicy())
        self.verify_checksum = verify_checksum
        self._transport = None
        self._parser = FrameParser(verify_checksum)
        self._demux = Demux(time.monotonic)
        self._comm = CommLog()
        self._subs: dict[Command, tuple[float, bool]] = {}  # device subscriptions to restore
        self._streams: dict[Command, list[S]] = {}
        # held while _streams, _subs and the demux's streams change (the blocking shell: its lock)
        self._state_lock: contextlib.AbstractContextManager[Any] = contextlib.nullcontext()
        self._closing = False
        self._opened_by = 0  # pid that connected it (lifetime)
        self.on_reconnect: Callable[[SystemFlag], None] | None = on_reconnect
        """Called with the system flags found after every reconnection."""
        self.on_connection_lost: Callable[[BaseException | None], None] | None = on_connection_lost
        """Called with the cause when the connection drops."""
        self.last_error: BaseException | None = None

    # ------------------------------------------------------------------ properties
    @property
    def connected(self) -> bool:
        return self._transport is not None

    @property
    def on_frame(self) -> CommHook | None:
        """Communication log hook: called with a :class:`CommEntry` for every frame in and out."""
        return self._comm.hook

    @on_frame.setter
    def on_frame(self, hook: CommHook | None) -> None:
        self._comm.hook = hook

    @property
    def demux(self) -> Demux:
        """The demultiplexer (counters ``unsolicited``, ``late``)."""
        return self._demux

    @property
    def _announces(self) -> bool:
        """TCP announces a disconnect (07h, 000 §1.4.2): without it the gripper raises FAST STOP."""
        return self.endpoint.scheme == "tcp"

    # ------------------------------------------------------------------ lifecycle steps
    def _connected(self) -> None:
        """A connection was made (the shell has set ``_transport``)."""
        self._backoff.connected()
        lifetime.opened(self)
        self._guard()
        log.debug("connected to %s", self.endpoint)

    def _lost(self, exc: BaseException | None) -> None:
        """The connection dropped (not by ``close()``): fail what waits, tell the user, reconnect if asked."""
        reason = f"connection to {self.endpoint} lost" + (f": {exc}" if exc else "")
        if not self._closing:
            log.warning("%s", reason)
        self.last_error = exc
        self._backoff.lost()
        auto = self.policy is not None and not self._closing
        self._drop(ConnectionLostError(reason), end_streams=not auto)
        if self.on_connection_lost is not None:
            self.on_connection_lost(exc)
        if auto:
            self._start_reconnecting()

    def _add_stream(self, stream: S) -> None:
        with self._state_lock:
            self._streams.setdefault(stream.command, []).append(stream)
            self._demux.add_stream(stream.command, stream)

    def _remove_stream(self, stream: S) -> bool:
        """Forget ``stream``; True when it was the last of its command (the subscription can end)."""
        cmd = stream.command
        with self._state_lock:
            self._demux.remove_stream(cmd, stream)
            lst = self._streams.get(cmd, [])
            if stream in lst:
                lst.remove(stream)
            if lst:
                return False
            self._streams.pop(cmd, None)
            self._subs.pop(cmd, None)
            return True

    def _revive_streams(self) -> None:
        for lst in list(self._streams.values()):
            for st in lst:
                st.revive()

    def _reconnected(self, flags: SystemFlag) -> SystemFlag:
        """Report the flags found after a reconnection; a FAST STOP is reported, never acknowledged."""
        if flags & SystemFlag.SF_FAST_STOP:
            log.warning("reconnected to %s: the gripper is in FAST STOP (not acknowledged)", self.endpoint)
        else:
            log.info("reconnected to %s", self.endpoint)
        if self.on_reconnect is not None:
            self.on_reconnect(flags)
        return flags

    def _attempt_failed(self, attempt: int, exc: BaseException) -> None:
        log.info("reconnect attempt %d to %s failed: %s", attempt, self.endpoint, exc)
        self._drop(ConnectionLostError(str(exc)), end_streams=False)

    def _give_up(self) -> None:
        log.error("giving up reconnecting to %s after %d attempts", self.endpoint, self._backoff.attempt)
        self._drop(ConnectionLostError("connection lost; reconnecting failed"), end_streams=True, forget=True)

    def _not_connected(self, cid: int) -> ConnectionLostError:
        return ConnectionLostError("not connected" if not self.last_error else
                                   f"not connected (last error: {self.last_error})", cid)

    # hooks the shell supplies
    def _drop(self, exc: ConnectionLostError, end_streams: bool, forget: bool = False) -> None:
        raise NotImplementedError

    def _start_reconnecting(self) -> None:
        raise NotImplementedError

    def _guard(self) -> None:
        """Arm :func:`lifetime.guard` for the new connection (warn and announce if collected open)."""
        raise NotImplementedError

    def _close_at_exit(self) -> None:
        """Close without an event loop or a wait (interpreter exit, see :mod:`pywsg.client.lifetime`)."""
        raise NotImplementedError

    # ------------------------------------------------------------------ frames in
    def _on_event(self, ev: Frame | ParseError) -> None:
        """A parsed frame or a parse error from the gripper."""
        if isinstance(ev, Frame):
            if self._comm.active:
                self._comm.frame(RX, ev)
            self._demux.feed(ev)
            return
        self._comm.error(RX, ev)
        if isinstance(ev, ChecksumMismatch):
            self._demux.feed_bad_checksum(ev, bad_checksum)
        elif not isinstance(ev, GarbageSkipped):
            log.warning("bad input from the gripper: %s", ev.message)

    def _read_wire(self, call: Call[Any]) -> bytes:
        """A read of a subscribed value repeats the subscription's flags: flags 0 would end it."""
        sub = self._subs.get(Command(call.command_id)) if call.auto_read else None
        return call.wire if sub is None else calls.subscribe(Command(call.command_id), *sub).wire

    def _expire(self, w: Waiter, timeout: float) -> None:
        """Fail ``w`` with TimeoutError; its late reply is dropped as a ghost's."""
        if not w.done:
            w.fail(TimeoutError(Status.E_TIMEOUT, w.command_id, f"no reply within {timeout:g} s",
                                from_device=False))
            self._demux.abandon(w)

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.endpoint} {'connected' if self.connected else 'closed'}>"

