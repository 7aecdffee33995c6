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
"""

from __future__ import annotations

import atexit
import logging
import os
import socket
import weakref
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
            g._close_at_exit()
        except Exception as exc:  # exit must go on
            log.debug("closing %r at exit: %s", g, exc)
    _OPEN.clear()


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
