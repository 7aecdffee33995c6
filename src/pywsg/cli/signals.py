"""Leaving on a signal without a FAST STOP.

A WSG raises FAST STOP when its TCP client goes away without announcing it (07h, command manual
000 §1.4.2, §3.1.2). A `wsg` command killed by SIGTERM (``timeout 0.8 wsg move 0``), SIGHUP (the terminal
of a ``wsg monitor`` closed) or SIGINT (Ctrl-C) therefore unwinds like an exception: the command's
``finally``/``with`` blocks close the connection, which announces the disconnect, and the process
exits with the shell convention 128 + signal number (130 for Ctrl-C, 143 for SIGTERM, 129 for SIGHUP).
"""

from __future__ import annotations

import asyncio
import contextlib
import signal
from collections.abc import Coroutine
from types import FrameType
from typing import Any, TypeVar

T = TypeVar("T")

SIGNALS = tuple(getattr(signal, name) for name in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, name))


class Interrupted(BaseException):
    """A signal asked the command to stop (a BaseException, so ``except Exception`` lets it through)."""

    def __init__(self, signum: int) -> None:
        super().__init__(signum)
        self.signum = signum

    @property
    def exit_code(self) -> int:
        return 128 + self.signum


def _raise(signum: int, _frame: FrameType | None) -> None:
    raise Interrupted(signum)


def install() -> None:
    """Turn SIGINT, SIGTERM and SIGHUP into :class:`Interrupted` in the main thread.

    A signal the parent set to be ignored stays ignored (``nohup wsg monitor``, a shell's ``&``)."""
    for sig in SIGNALS:
        with contextlib.suppress(ValueError, OSError):  # not the main thread / not on this OS
            if signal.getsignal(sig) is not signal.SIG_IGN:
                signal.signal(sig, _raise)


def run(coro: Coroutine[Any, Any, T]) -> T:
    """``asyncio.run(coro)``, but a signal cancels the task (so its ``finally`` closes the gripper
    with 07h) and then raises :class:`Interrupted`."""
    received: list[int] = []

    async def main() -> T:
        loop = asyncio.get_running_loop()
        task = asyncio.current_task()
        assert task is not None

        def stop(sig: int) -> None:
            if not received:  # the first signal cancels; the cleanup then runs undisturbed
                received.append(sig)
                task.cancel()

        for sig in SIGNALS:
            if signal.getsignal(sig) is signal.SIG_IGN:
                continue  # ignored by the parent: keep it so
            with contextlib.suppress(NotImplementedError, ValueError, RuntimeError):
                loop.add_signal_handler(sig, stop, sig)
        return await coro

    ours = signal.getsignal(signal.SIGTERM) is _raise
    try:
        result = asyncio.run(main())
    except asyncio.CancelledError:
        if received:
            raise Interrupted(received[0]) from None
        raise
    finally:
        if ours:
            install()  # closing the loop reset the signals to their defaults: ours come back
    if received:
        raise Interrupted(received[0])
    return result
