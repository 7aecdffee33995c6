"""Connection caps for the Modbus/TCP and web ports, with a file-descriptor reserve.

Every accepted connection holds a file descriptor. Without a cap ~1,100 idle connections exhaust the
common ``ulimit -n 1024``, and then *every* listening socket of the process - the gripper's command
port included - fails to accept. So each capped server refuses (accepts and at once closes) a
connection beyond its own cap, and any capped server refuses once the process's open descriptors come
within :data:`FD_RESERVE` of the soft limit: that reserve keeps the command interface (capped at 16
per gripper by :class:`~pywsg.server.limits.Limits`) and the process's own files working.
"""

from __future__ import annotations

import asyncio
import functools
import logging
import os
from collections.abc import Callable
from typing import Any

log = logging.getLogger("pywsg.server.conncap")

FD_RESERVE = 64
"""Descriptors kept free for the command interfaces, ptys, settings and log files."""


def fd_limit() -> int | None:
    """The soft RLIMIT_NOFILE, or None where unknown/unlimited."""
    try:
        import resource
    except ImportError:  # pragma: no cover - Windows
        return None
    soft, _ = resource.getrlimit(resource.RLIMIT_NOFILE)
    return None if soft == resource.RLIM_INFINITY else int(soft)


def open_fds() -> int | None:
    """Descriptors this process holds (Linux /proc, else None)."""
    try:
        return len(os.listdir("/proc/self/fd"))
    except OSError:
        return None


def fds_left(reserve: int = FD_RESERVE) -> bool:
    """False when accepting one more connection would eat into the reserve."""
    limit = fd_limit()
    if limit is None:
        return True
    used = open_fds()
    return used is None or used < limit - reserve


class Refuse(asyncio.Protocol):
    """Closes the accepted connection at once (the client sees a reset, not a hang)."""

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        transport.abort()  # type: ignore[attr-defined]


class Cap:
    """Decides whether a server with ``count()`` open connections may accept another."""

    def __init__(self, name: str, limit: int, count: Callable[[], int]) -> None:
        if limit < 1:
            raise ValueError(f"{name}: connection cap must be at least 1")
        self.name = name
        self.limit = limit
        self.count = count
        self.refused = 0

    def allow(self) -> bool:
        if self.count() < self.limit and fds_left():
            return True
        if self.refused % 100 == 0:
            log.warning("%s: connection refused (%d open, cap %d, or file descriptors low)",
                        self.name, self.count(), self.limit)
        self.refused += 1
        return False


def cap_modbus_server(server: Any, limit: int) -> Cap:
    """Cap a pymodbus ``ModbusTcpServer`` before its ``listen()``: new connections beyond ``limit``
    (or into the descriptor reserve) are refused."""
    cap = Cap("modbus", limit, lambda: len(server.active_connections))
    accept = server.handle_new_connection

    def handle_new_connection() -> Any:
        return accept() if cap.allow() else Refuse()

    # pymodbus 3.16 binds the protocol factory into ``call_create`` (a partial of create_server)
    # when the server object is made: swap it there.
    create = getattr(server, "call_create", None)
    if not isinstance(create, functools.partial) or not create.args or create.args[0] != accept:
        raise RuntimeError("pymodbus server layout changed: cannot cap Modbus/TCP connections")
    server.call_create = functools.partial(create.func, handle_new_connection, *create.args[1:], **create.keywords)
    return cap


def capped_http_protocol(limit: int) -> type[asyncio.Protocol]:
    """uvicorn's HTTP protocol (``uvicorn.Config(http=...)``) refusing connections beyond ``limit``
    open HTTP and WebSocket connections (or into the descriptor reserve)."""
    from uvicorn.protocols.http.auto import AutoHTTPProtocol

    base: Any = AutoHTTPProtocol

    cap = Cap("web", limit, lambda: 0)

    class CappedHTTPProtocol(base):  # type: ignore[misc]
        _refused = False

        def connection_made(self, transport: Any) -> None:
            conns = self.connections  # uvicorn's set of open HTTP and WebSocket connections
            cap.count = lambda: len(conns)
            if not cap.allow():
                self._refused = True
                transport.abort()
                return
            super().connection_made(transport)

        def connection_lost(self, exc: Exception | None) -> None:
            if not self._refused:
                super().connection_lost(exc)

    return CappedHTTPProtocol
