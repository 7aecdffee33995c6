"""Connection caps for the Modbus/TCP and web ports, with a file-descriptor reserve.

Every accepted connection holds a file descriptor. Without a cap ~1,100 idle connections exhaust the
common ``ulimit -n 1024``, and then *every* listening socket of the process - the gripper's command
port included - fails to accept. So each capped server refuses (accepts and at once closes) a
connection beyond its own cap, and any capped server refuses once the process's open descriptors come
within :data:`FD_RESERVE` of the soft limit: that reserve keeps the command interface (capped at 16
per gripper by :class:`~pywsg.server.limits.Limits`) and the process's own files working.

A cap alone lets a few silent peers hold every slot, so each capped connection also has an idle
timeout (:class:`IdleWatch`): no data either way for that long and it is closed. A polling Modbus
master, a browser page loading, a WebSocket the server pushes to are never idle.
"""

from __future__ import annotations

import asyncio
import functools
import json
import logging
import os
import socket
import struct
import types
from collections.abc import Callable
from typing import Any

from .ratelimit import RequestRate, client_key, retry_after

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


_TCP_INFO = getattr(socket, "TCP_INFO", None)


def _since_data(transport: Any) -> float | None:
    """Seconds since data last left or reached this socket (Linux ``TCP_INFO``
    ``tcpi_last_data_sent`` / ``tcpi_last_data_recv``), None where unknown: the server's own pushes
    (WebSocket updates) count as activity, and so do reads after a WebSocket upgrade, which go to
    uvicorn's WebSocket protocol and not to :meth:`IdleWatch.touch`."""
    sock = transport.get_extra_info("socket")
    if _TCP_INFO is None or sock is None:
        return None
    try:
        info = sock.getsockopt(socket.IPPROTO_TCP, _TCP_INFO, 104)
    except (OSError, ValueError):  # closed: uvloop's pseudo-socket raises ValueError (fd -1)
        return None
    if len(info) < 56:
        return None
    # after 8 bytes of u8 fields and 9 u32s: last_data_sent, last_ack_sent, last_data_recv (ms)
    sent_ms, _, recv_ms = struct.unpack_from("=III", info, 44)
    return float(min(sent_ms, recv_ms)) / 1000.0


class IdleWatch:
    """Closes ``transport`` after ``timeout`` s without data received (:meth:`touch`) or sent.

    One timer per connection, re-armed for the remaining time only when it fires: a busy connection
    costs one call per ``timeout``, not one per read. ``timeout`` 0 or None: never.
    """

    def __init__(self, name: str, transport: Any, timeout: float | None) -> None:
        self.name = name
        self.transport = transport
        self.timeout = timeout
        self.loop = asyncio.get_running_loop()
        self.last = self.loop.time()
        self._timer: asyncio.TimerHandle | None = None
        if timeout:
            self._timer = self.loop.call_later(timeout, self._check)

    def touch(self) -> None:
        self.last = self.loop.time()

    def _check(self) -> None:
        assert self.timeout
        if self.transport.is_closing():
            # closed without our connection_lost: after a WebSocket upgrade uvicorn hands the transport
            # to its WebSocket protocol, which gets connection_lost instead. Nothing left to watch.
            self._timer = None
            return
        idle = self.loop.time() - self.last
        sent = _since_data(self.transport)
        if sent is not None:
            idle = min(idle, sent)
        if idle < self.timeout:
            self._timer = self.loop.call_later(self.timeout - idle, self._check)
            return
        self._timer = None
        log.info("%s: closing a connection idle for %.0f s", self.name, idle)
        self.transport.close()

    def cancel(self) -> None:
        if self._timer is not None:
            self._timer.cancel()
            self._timer = None


def watch_idle(name: str, protocol: Any, timeout: float | None) -> Any:
    """Give an asyncio ``protocol`` instance an :class:`IdleWatch` (wraps its connection_made,
    data_received and connection_lost); returns it."""
    if not timeout:
        return protocol
    made, received, lost = protocol.connection_made, protocol.data_received, protocol.connection_lost
    holder: list[IdleWatch] = []

    def connection_made(transport: Any) -> None:
        holder.append(IdleWatch(name, transport, timeout))
        made(transport)

    def data_received(data: bytes) -> None:
        if holder:
            holder[0].touch()
        received(data)

    def connection_lost(exc: Exception | None) -> None:
        if holder:
            holder[0].cancel()
        lost(exc)

    protocol.connection_made = connection_made
    protocol.data_received = data_received
    protocol.connection_lost = connection_lost
    return protocol


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


def cap_modbus_server(server: Any, limit: int, idle_timeout: float | None = None) -> Cap:
    """Cap a pymodbus ``ModbusTcpServer`` before its ``listen()``: new connections beyond ``limit``
    (or into the descriptor reserve) are refused, and one without data for ``idle_timeout`` s is closed."""
    cap = Cap("modbus", limit, lambda: len(server.active_connections))
    accept = server.handle_new_connection

    def handle_new_connection() -> Any:
        return watch_idle("modbus", accept(), idle_timeout) if cap.allow() else Refuse()

    # pymodbus 3.16 binds the protocol factory into ``call_create`` (a partial of create_server)
    # when the server object is made: swap it there.
    create = getattr(server, "call_create", None)
    if not isinstance(create, functools.partial) or not create.args or create.args[0] != accept:
        raise RuntimeError("pymodbus server layout changed: cannot cap Modbus/TCP connections")
    server.call_create = functools.partial(create.func, handle_new_connection, *create.args[1:], **create.keywords)
    return cap


REFUSAL_LOG_INTERVAL = 10.0
"""Seconds between two log lines about requests refused for their rate."""

OVERFLOW_KEY = "?"
"""Rate-limit key of a connection whose peer address is unknown."""

#: Bytes handed to the HTTP parser at a time, so a pipelined flood is cut within one slice of the
#: request that spends the connection's budget instead of after a whole 256 KiB read.
HTTP_FEED_SLICE = 4096


#: Stands in for a request dropped past the budget: "already answered", so uvicorn ignores its body.
#: (``message_event``: uvicorn's connection_lost sets the current cycle's event.)
_DROPPED = types.SimpleNamespace(response_complete=True, disconnected=True, keep_alive=False,
                                 message_event=types.SimpleNamespace(set=lambda: None))


class TooManyRequests:
    """The answer to a request over its client's rate: ``429 Too Many Requests`` with ``Retry-After``
    (whole seconds) and a JSON ``detail`` in the web interface's error style, built once per
    ``Retry-After`` value."""

    def __init__(self, rates: RequestRate) -> None:
        self.rates = rates
        self._built: dict[int, tuple[list[tuple[bytes, bytes]], bytes, bytes]] = {}

    def _build(self, wait: float) -> tuple[list[tuple[bytes, bytes]], bytes, bytes]:
        retry = retry_after(wait)
        built = self._built.get(retry)
        if built is None:
            body = json.dumps({"detail": (
                f"too many requests from your address: at most {self.rates.rate:g} per second on average, "
                f"bursts of {self.rates.burst}; try again in {retry} s")}).encode()
            headers = [(b"content-type", b"application/json"), (b"content-length", str(len(body)).encode()),
                       (b"retry-after", str(retry).encode()), (b"cache-control", b"no-store"),
                       (b"connection", b"close")]
            raw = b"".join([b"HTTP/1.1 429 Too Many Requests\r\n",
                            *(name + b": " + value + b"\r\n" for name, value in headers), b"\r\n", body])
            built = (headers, body, raw)
            if len(self._built) < 64:  # Retry-After values seen: 1 s at any rate of 1/s or more
                self._built[retry] = built
        return built

    def raw(self, wait: float, head: bool = False) -> bytes:
        """The whole answer as bytes, for a connection with nothing else in flight (``head``: to a
        HEAD request, without the body)."""
        _, body, raw = self._build(wait)
        return raw[:len(raw) - len(body)] if head else raw

    def app(self, wait: float) -> Any:
        """The answer as an ASGI app, for uvicorn to send in order after the answers before it."""
        headers, body, _ = self._build(wait)

        async def app(scope: Any, receive: Any, send: Any) -> None:
            await send({"type": "http.response.start", "status": 429, "headers": headers})
            await send({"type": "http.response.body", "body": body})

        return app


def capped_http_protocol(limit: int, idle_timeout: float | None = None,
                         requests_per_connection: int | None = 100,
                         rates: RequestRate | None = None) -> type[asyncio.Protocol]:
    """uvicorn's HTTP protocol (``uvicorn.Config(http=...)``) refusing connections beyond ``limit``
    open HTTP and WebSocket connections (or into the descriptor reserve), and closing one with no
    data either way for ``idle_timeout`` s (a WebSocket the server pushes to is not idle).

    ``requests_per_connection`` (None: no limit) is the keep-alive request budget, like Apache's
    ``MaxKeepAliveRequests`` / nginx's ``keepalive_requests``: the last request it allows is answered
    with ``Connection: close``; anything pipelined after it is read and dropped, unparsed, and the
    connection closes once the answers before it are out. A browser opens a new connection; a client
    pipelining a megabyte of requests costs at most the budget's worth of requests.

    ``rates`` (None: no limit) is the per-client request rate limit, checked before the app sees the
    request: a request from an address whose bucket is empty is answered ``429 Too Many Requests``
    (:class:`TooManyRequests`, in order after the answers before it) with ``Connection: close``, and
    the rest of that connection is dropped unparsed like a spent budget. So a client over its rate
    costs one short answer per connection, not a trip through the app per request."""
    from uvicorn.protocols.http.auto import AutoHTTPProtocol

    base: Any = AutoHTTPProtocol
    # h11 serves pipelined requests one at a time from its own buffer; the budget hooks httptools'
    # per-request callback (uvicorn's choice when httptools is installed, as here)
    httptools = hasattr(base, "on_headers_complete")
    budget = requests_per_connection if httptools else None
    if rates is not None and not httptools:
        log.warning("web: no httptools, so no request rate limit (pip install 'uvicorn[standard]')")
        rates = None

    cap = Cap("web", limit, lambda: 0)
    too_many = TooManyRequests(rates) if rates is not None else None
    refusal_logged = [float("-inf")]  # loop time of the last "over the rate limit" log line

    class CappedHTTPProtocol(base):  # type: ignore[misc]
        app: Any  # uvicorn's: the ASGI app this connection's requests run
        _refused = False
        _idle: IdleWatch | None = None

        def connection_made(self, transport: Any) -> None:
            conns = self.connections  # uvicorn's set of open HTTP and WebSocket connections
            cap.count = lambda: len(conns)
            if not cap.allow():
                self._refused = True
                transport.abort()
                return
            if idle_timeout:
                self._idle = IdleWatch("web", transport, idle_timeout)
            super().connection_made(transport)
            if rates is not None:
                self._rate_key = client_key(str(self.client[0])) if self.client else OVERFLOW_KEY

        _requests = 0
        _spent = False
        _last: Any = None  # the budget's last request, while its body comes in
        _rate_key = ""

        def data_received(self, data: bytes) -> None:
            if self._idle is not None:
                self._idle.touch()
            if budget is None and rates is None:
                super().data_received(data)
                return
            for i in range(0, len(data), HTTP_FEED_SLICE):
                if self._spent or self.transport.is_closing():
                    return  # past the budget: dropped unparsed, the connection closes after the answers
                super().data_received(data[i:i + HTTP_FEED_SLICE])

        def on_headers_complete(self) -> None:
            if self._spent:
                # pipelined in the same slice after the last allowed request: never run; a finished
                # stand-in cycle makes the parser callbacks ignore its body
                self.cycle = _DROPPED
                return
            self._requests += 1
            before = self.cycle
            if rates is not None and (wait := rates.take(self._rate_key)):
                self._refuse(rates, wait, before)
                return
            super().on_headers_complete()
            if budget is not None and self._requests >= budget:
                if self.cycle is not before:
                    self.cycle.keep_alive = False  # answered with Connection: close, then closed
                    self._last = self.cycle  # its body may still come in: dropping starts after it
                else:
                    self._spent = True

        def on_message_complete(self) -> None:
            super().on_message_complete()
            if self._last is not None and self.cycle is self._last:
                self._last = None
                self._spent = True  # the budget's last request is whole: what follows is dropped

        def _refuse(self, limiter: RequestRate, wait: float, before: Any) -> None:
            """Over the client's rate: a short 429 instead of the app, in order after the answers
            before it; then the connection closes and the rest is dropped, as for a spent budget."""
            self._spent = True
            now = self.loop.time()
            if now - refusal_logged[0] >= REFUSAL_LOG_INTERVAL:  # one line per interval, not per 429
                refusal_logged[0] = now
                log.warning("web: %s over the request rate limit (%d requests refused so far)",
                            self._rate_key, limiter.refused)
            assert too_many is not None
            if before is None or (before.response_complete and not self.pipeline):
                # nothing in flight (a new connection, as a flood makes them): the pre-built answer,
                # no request cycle, no task
                self.cycle = _DROPPED
                self.transport.write(too_many.raw(wait, head=self.parser.get_method() == b"HEAD"))
                self.transport.close()
                return
            app = self.app
            self.app = too_many.app(wait)
            try:
                super().on_headers_complete()
            finally:
                self.app = app
            if self.cycle is not before:
                self.cycle.keep_alive = False

        def _should_upgrade(self) -> bool:
            return not self._spent and bool(super()._should_upgrade())

        def _unsupported_upgrade_warning(self) -> None:
            if not self._spent:  # a refused or dropped WebSocket upgrade is not worth a warning
                super()._unsupported_upgrade_warning()

        def connection_lost(self, exc: Exception | None) -> None:
            if self._idle is not None:
                self._idle.cancel()
            if not self._refused:
                super().connection_lost(exc)

    return CappedHTTPProtocol
