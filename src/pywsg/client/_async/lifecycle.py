"""The driver's flows that wait on the gripper but do not depend on how it waits, said once:
:class:`AsyncLifecycle` (mixed into :class:`~pywsg.client.AsyncGripper`).

This file is the source: ``_sync/generated_lifecycle.py`` (``Lifecycle``, mixed into the blocking
:class:`~pywsg.client.Gripper`) is generated from it by ``scripts/unasync_client.py``, as the command
methods are. Here: the disconnect announcement, ``reconnect()`` and the automatic reconnection with
its back-off (:mod:`pywsg.client.reconnect`), stream subscriptions, the reply of an immediate command that is not
E_SUCCESS, a motion's first reply, the system flags for an error report, and ``request()``. What
differs between the shells is reached through a few hooks each supplies: ``connect``, ``_drop``,
``_pause`` (sleep), ``_wait_closed``, ``_final_frame`` (wait for a final frame), ``_forget_final``,
``_resume_streams``, ``_streams_idle``, and the hot path ``_run`` / ``_exchange``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, TypeVar, cast

from ...errors import ConnectionLostError, WsgError
from ...protocol import Frame, Status, SystemFlag
from .. import calls
from ..calls import Call
from ..core import decode_success, is_success, needs_flags, raise_for, status_of
from ..demux import Waiter
from ..shell import ShellBase, log
from ..types import Reply
from . import handles
from .handles import AsyncMotion, AsyncStream, AWaiter

T = TypeVar("T")


class AsyncLifecycle(ShellBase[AsyncStream]):
    """Reconnection, error reports and raw requests of the driver, over the shell's hooks."""

    if TYPE_CHECKING:  # supplied by the shell
        async def connect(self) -> None: ...

        async def system_state(self) -> SystemFlag: ...

        async def _run(self, call: Call[T], timeout: float | None = None) -> T: ...

        async def _exchange(self, call: Call[Any], timeout: float | None) -> tuple[Frame, AWaiter | None]: ...

        async def _pause(self, delay: float) -> None: ...

        async def _wait_closed(self) -> None: ...

        async def _final_frame(self, final: AWaiter, timeout: float) -> Frame: ...

        def _forget_final(self, final: Waiter) -> None: ...

        def _resume_streams(self) -> None: ...

        def _streams_idle(self) -> None: ...

    # ------------------------------------------------------------------ connection
    async def _announce_disconnect(self) -> None:
        """TCP: send 07h Disconnect and wait for its reply (at most 1 s), so the gripper does not FAST STOP."""
        if self._transport is not None and self._announces:
            try:
                await self._run(calls.disconnect(), timeout=min(self.timeout, 1.0))
            except WsgError as exc:
                log.debug("disconnect announcement: %s", exc)

    async def reconnect(self) -> SystemFlag:
        """Close (announcing the disconnect if the link still works) and connect again; restore the
        subscriptions. Returns the system flags found; a FAST STOP is reported (log warning,
        ``on_reconnect``), never acknowledged."""
        if self._transport is not None:
            await self._announce_disconnect()
            self._drop(ConnectionLostError("reconnecting"), end_streams=False)
            await self._wait_closed()  # the gripper must see the old connection go before the new one
        await self.connect()
        self._revive_streams()
        for cmd, (period, change_only) in list(self._subs.items()):
            await self._run(calls.subscribe(cmd, period, change_only))
        self._resume_streams()
        return self._reconnected(await self.system_state())

    async def _auto_reconnect(self) -> bool:
        """Reconnect under the policy's back-off; False when closed or given up (the streams end)."""
        backoff = self._backoff
        while self.policy is not None and not self._closing:
            delay = backoff.next_delay()
            if delay is None:
                self._give_up()
                return False
            await self._pause(delay)
            if self._closing:
                break
            try:
                await self.reconnect()
                return True
            except WsgError as exc:
                self._attempt_failed(backoff.attempt, exc)
        return False

    # ------------------------------------------------------------------ streams
    async def _open_stream(self, stream: AsyncStream, period: float, change_only: bool) -> AsyncStream:
        """Register ``stream`` and subscribe its command on the device (kept to restore on reconnect)."""
        cmd = stream.command
        self._add_stream(stream)
        try:
            await self._run(calls.subscribe(cmd, period, change_only))
        except BaseException:
            self._remove_stream(stream)
            raise
        self._subs[cmd] = (period, change_only)
        self._resume_streams()
        return stream

    async def _unsubscribe(self, stream: AsyncStream) -> None:
        """Forget ``stream``; end the device's subscription with the last stream of its command."""
        if self._remove_stream(stream) and self._transport is not None:
            try:
                await self._run(calls.unsubscribe(stream.command))
            except WsgError as exc:
                log.debug("unsubscribe %s: %s", stream.command.name, exc)
        if not self._streams:
            self._streams_idle()

    # ------------------------------------------------------------------ replies
    async def _result(self, call: Call[T], frame: Frame) -> T:
        """The result of a reply the hot path did not settle: decoded, None, or the error to raise."""
        if is_success(frame):
            return decode_success(call, frame)
        st = status_of(frame)
        if st in call.none_on:
            return None  # type: ignore[return-value]
        flags = await self._flags_quietly() if needs_flags(call, st) else None
        raise raise_for(call, frame, flags)

    async def _run_motion(self, call: Call[Any], wait: bool, timeout: float | None) -> AsyncMotion:
        """A motion command: its first reply, then (``wait``) its final frame."""
        frame, final = await self._exchange(call, None)
        st = status_of(frame)
        if st == Status.E_CMD_PENDING:
            motion = AsyncMotion(cast(handles.Host, self), call, final)
        else:
            if final is not None:
                self._forget_final(final)
            if st != Status.E_SUCCESS:
                flags = await self._flags_quietly()
                raise raise_for(call, frame, flags)
            motion = AsyncMotion(cast(handles.Host, self), call, None, frame)
        if wait:
            await motion.wait(timeout)
        return motion

    async def _flags_quietly(self) -> SystemFlag | None:
        """The system flags for an error report, or None if they cannot be read."""
        if self._transport is None:
            return None
        try:
            frame, _ = await self._exchange(calls.system_state(), min(self.timeout, 0.5))
            if status_of(frame) == Status.E_SUCCESS:
                return decode_success(calls.system_state(), frame)
        except WsgError:
            pass
        return None

    async def request(self, command_id: int, payload: bytes = b"", *, check: bool = True,
                      timeout: float | None = None) -> Reply:
        """Raw request for custom commands (e.g. an on-board script's ID). Waits for a final frame
        after E_CMD_PENDING. With ``check`` an error status raises; else it is in ``Reply.status``."""
        call = calls.raw(command_id, payload)
        frame, final = await self._exchange(call, timeout)
        if status_of(frame) == Status.E_CMD_PENDING and final is not None:
            frame = await self._final_frame(final, self.motion_timeout if timeout is None else timeout)
        elif final is not None:
            self._forget_final(final)
        st = status_of(frame)
        if check and st != Status.E_SUCCESS:
            raise raise_for(call, frame, None)
        return Reply(frame.command_id, st, frame.params)
