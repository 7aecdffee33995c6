"""Grippers left open: announced at a clean interpreter exit, warned about when garbage-collected.

A WSG raises FAST STOP when a TCP connection closes without the disconnect announcement (07h,
000 §1.4.2, §3.1.2): a lost connection must stop the fingers. A script that simply ends without ``close()``
is not a lost connection, so every gripper still open when the interpreter exits cleanly is
closed here the normal way (07h, then close). A gripper garbage-collected while open gets a
``ResourceWarning`` (like an unclosed file; shown with ``python -W default`` or ``-X dev``) and its
disconnect is announced without waiting for the reply. A process killed (SIGKILL, power loss) or a
cable pulled announces nothing: the gripper goes to FAST STOP, as it must.

The registry holds weak references only: it never keeps a gripper alive. A forked child process
inherits the parent's open grippers (and their sockets) but never announces them: that would end the
parent's session.

The announcement at collection is a weak reference's callback (:func:`guard`), not the gripper's
``__del__``: a gripper is usually part of a reference cycle (its reader or its protocol's callbacks
point back at it), and the order in which the garbage collector finalizes the objects of a cycle is
unspecified. On Python 3.10 the socket's own finalizer (and asyncio's transport's) ran before the
gripper's ``__del__`` and closed the descriptor, so the 07h was never sent and the gripper raised FAST
STOP; 3.11 happened to finalize them the other way round. The collector calls weak reference callbacks
before any finalizer, and the callback holds the socket, so the socket is still open when it runs.
"""

from __future__ import annotations

import atexit
import logging
import os
import socket
import warnings
import weakref
from collections.abc import Callable
from typing import Any, Protocol

from . import calls

log = logging.getLogger("pywsg.client")


class _Closable(Protocol):
    _opened_by: int  # pid of the process that connected it

    def _close_at_exit(self) -> None: ...


_OPEN: weakref.WeakSet[Any] = weakref.WeakSet()


def opened(gripper: _Closable) -> None:
    gripper._opened_by = os.getpid()
    _OPEN.add(gripper)


def closed(gripper: _Closable) -> None:
    _OPEN.discard(gripper)
    unguard(gripper)


def owned(gripper: _Closable) -> bool:
    """Connected by this process (not inherited through fork). Kept on the gripper itself: during a
    collection its weak references are already cleared when ``__del__`` asks."""
    return getattr(gripper, "_opened_by", None) == os.getpid()


@atexit.register
def _close_all() -> None:
    """Announce the disconnect of every gripper still open (runs after the main script ends)."""
    for g in [g for g in list(_OPEN) if owned(g)]:
        try:
            log.info("closing %r at interpreter exit (disconnect announced)", g)
            unguard(g)
            g._close_at_exit()
        except Exception as exc:  # exit must go on
            log.debug("closing %r at exit: %s", g, exc)
    _OPEN.clear()


_GUARDS: dict[int, weakref.ref[Any]] = {}  # id(gripper) -> its weak reference with the callback


def guard(gripper: Any, sock: Any, advice: str, close: Callable[[], None] | None = None) -> None:
    """Warn and announce the disconnect on ``sock`` (None: warn only), then ``close()``, if ``gripper``
    is collected before :func:`unguard` (``close()``, a dropped connection). ``advice`` ends the
    warning. Neither ``sock`` nor ``close`` may reach the gripper (that would keep it alive)."""
    key, pid = id(gripper), os.getpid()
    text = f"unclosed {gripper!r}: disconnect announced at garbage collection; {advice}"

    def collected(ref: weakref.ref[Any]) -> None:
        if _GUARDS.get(key) is ref:
            del _GUARDS[key]
        if os.getpid() != pid:  # a forked child never announces the parent's session
            return
        warnings.warn(text, ResourceWarning, stacklevel=1)
        if sock is not None:
            announce_on_socket(sock)
        if close is not None:
            close()

    _GUARDS[key] = weakref.ref(gripper, collected)


def unguard(gripper: Any) -> None:
    """The gripper closed its connection: nothing to announce when it is collected."""
    _GUARDS.pop(id(gripper), None)


def announce_on_socket(sock: Any) -> None:
    """Write the 07h request on a TCP socket now, without a reply and without the event loop
    (a garbage-collected or exiting :class:`AsyncGripper` has no running loop), then shut it down.
    ``sock`` is a socket or asyncio's wrapper of one."""
    try:
        fd = sock.fileno()
        if fd < 0:
            return
        with socket.socket(fileno=os.dup(fd)) as s:
            s.setblocking(True)
            s.settimeout(0.5)
            s.sendall(calls.disconnect().wire)
            s.shutdown(socket.SHUT_RDWR)  # the FIN follows the request: the gripper reads 07h first
    except OSError as exc:
        log.debug("disconnect announcement on close: %s", exc)
