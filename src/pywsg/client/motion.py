"""What :class:`~pywsg.client.Motion` and :class:`~pywsg.client.AsyncMotion`
share: the call, its final waiter (or the final frame, when the motion was already over) and the
outcome. The shells add only the waiting, blocking or awaited."""

from __future__ import annotations

import time
from typing import Any

from ..errors import TimeoutError
from ..protocol import Command, Frame, Status
from .calls import Call
from .core import raise_for, status_of
from .demux import Waiter


class MotionBase:
    """A running motion; ``done()``, ``status`` and the outcome bookkeeping of ``wait()``."""

    def __init__(self, call: Call[Any], final: Waiter | None, frame: Frame | None = None) -> None:
        self._call = call
        self._final = final
        self._frame = frame  # set when the motion is already over
        self._error: BaseException | None = None
        self._checked = False
        self.command = Command(call.command_id)
        self.started = time.monotonic()

    def done(self) -> bool:
        """True once the final frame arrived (or the connection failed)."""
        return self._frame is not None or (self._final is not None and self._final.done)

    @property
    def status(self) -> Status | int | None:
        """The final status, or None while the motion runs."""
        if self._final is not None and self._final.frame is not None:
            return status_of(self._final.frame)
        return status_of(self._frame) if self._frame is not None else None

    def _waiting(self) -> bool:
        """True while the final frame is still to come (the shell then waits for ``self._final``)."""
        return self._frame is None and self._final is not None and not self._final.done

    def _timed_out(self, timeout: float) -> TimeoutError:
        return TimeoutError(Status.E_TIMEOUT, self._call.command_id,
                            f"motion not finished within {timeout:g} s", from_device=False)

    def _failed(self) -> bool:
        """Take the final frame (or the connection error); True when its status is an error whose
        exception the shell still has to build with :meth:`_fail` (it reads the system flags first)."""
        w = self._final
        if self._frame is None and w is not None:
            if w.error is not None:
                self._error = w.error
                self._checked = True
                return False
            self._frame = w.frame
        assert self._frame is not None
        if status_of(self._frame) == Status.E_SUCCESS:
            self._checked = True
            return False
        return True

    def _fail(self, flags: Any) -> None:
        assert self._frame is not None
        self._error = raise_for(self._call, self._frame, flags)
        self._checked = True

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.command.name} {'done' if self.done() else 'running'}>"
