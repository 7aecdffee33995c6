"""The virtual gripper's web interface (issue 6): ``create_app`` puts the parts together, ``serve_web`` runs it.

``serve_web(gripper, host, port)`` starts it on the running asyncio loop (what ``wsg sim --web-port``
does); ``create_app(...)`` gives the ASGI app alone. The parts, one module each:

- ``context``  the shared state: the web's own device session, the log feed, error style
- ``auth``     the guard every request passes (session, permissions, CSRF) and login/logout
- ``pages``    the HTML pages and the menu
- ``help_docs`` the project docs rendered as pages, and the downloads
- ``interface_page`` Settings → Command Interface: the stored interface and network values
- ``api``      the JSON API under /api (state, motion, settings, log, fieldbus)
- ``device_api`` identity (50h–52h), the Motion page's commands (42h, 34h–38h, jog), Scripting
- ``sim_api``  fault injection under /api/sim (Simulation page)
- ``world_api`` the same for scripts under /api/world (no cookies; own access rules)
- ``live``     the WebSocket /ws (20 Hz updates)
- ``health``   GET /healthz for container health checks and probes (no login, no device session)

Units everywhere: mm, mm/s, mm/s², N, °C. See docs/web.md for the API and the security rules.
"""

from __future__ import annotations

import asyncio
import contextlib
import dataclasses
import logging
import secrets
import socket
import sys
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import Any

import uvicorn
from fastapi import APIRouter, FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse, Response
from fastapi.staticfiles import StaticFiles
from starlette.exceptions import HTTPException as StarletteHTTPException

from .. import __version__
from . import api, auth, device_api, health, help_docs, interface_page, live, pages, sim_api, world_api
from .context import CommandBridge, InputError, LogFeed, WebContext, error
from .security import Auth, is_loopback_host

log = logging.getLogger(__name__)

STATIC = Path(__file__).resolve().parent / "static"

REQUEST_RATE = 20.0
"""Default per-client request rate limit (requests/s on average; docs/web.md "Request rate limit")."""
REQUEST_BURST = 200
"""Default burst: requests a client may make at once before the rate applies."""

# Every router of the web interface, in the order they are included. A new part of the interface
# is a module with ``router(ctx) -> APIRouter`` and one line here.
ROUTERS: list[Callable[[WebContext], APIRouter]] = [
    health.router,
    pages.router,
    help_docs.router,
    auth.router,
    api.router,
    device_api.router,
    sim_api.router,
    world_api.router,
    live.router,
    interface_page.router,
]


def create_app(gripper: Any, *, loopback: bool = True, password: str | None = None, fieldbus: Any = None,
               sim_info: Any = None, settings_path: str | Path | None = None, host: str | None = None,
               allowed_hosts: Sequence[str] = ()) -> FastAPI:
    """The ASGI app for ``gripper``. ``loopback``: whether it is bound to a loopback address only.

    ``host``: the bound address (``Host`` headers naming it are accepted; None or a wildcard
    address: any IP address literal); ``allowed_hosts``: further names it is reached by, besides
    localhost, 127.0.0.1 and [::1].
    """
    if settings_path is None:
        settings_path = getattr(gripper, "settings_path", None)
    ctx = WebContext(
        gripper=gripper, auth=Auth(loopback=loopback, password=password), bridge=CommandBridge(gripper),
        log_feed=LogFeed(getattr(gripper, "log", None), getattr(gripper, "clock", None)), fieldbus=fieldbus,
        sim_info=sim_info, settings_path=Path(settings_path) if settings_path else None,
    )
    # no Swagger/ReDoc pages: they load scripts from a CDN
    app = FastAPI(title="pywsg web interface", version=__version__, docs_url=None, redoc_url=None,
                  openapi_url="/api/openapi.json")
    app.state.ctx = ctx
    app.mount("/static", StaticFiles(directory=STATIC), name="static")

    @app.exception_handler(RequestValidationError)
    async def _invalid(request: Request, exc: RequestValidationError) -> JSONResponse:
        errors: dict[str, str] = {}
        for err in exc.errors():
            loc = [str(p) for p in err.get("loc", ()) if p not in ("body", "query", "path")]
            errors[".".join(loc) or "_"] = str(err.get("msg", "invalid"))
        return error(422, "invalid input: " + "; ".join(f"{k}: {v}" for k, v in errors.items()), errors)

    @app.exception_handler(StarletteHTTPException)
    async def _http_error(request: Request, exc: StarletteHTTPException) -> Response:
        # a browser asking for a page gets a page; API clients and scripts get the JSON error
        wants_page = not request.url.path.startswith("/api/") and "text/html" in request.headers.get("accept", "")
        if exc.status_code == 404 and wants_page and hasattr(request.state, "websession"):
            return pages.not_found_page(ctx, request, f"There is no page {request.url.path}.")
        if exc.status_code == 400 and exc.detail == "There was an error parsing the body":
            # FastAPI's answer when json.loads itself fails (RecursionError on 5,000 nested arrays):
            # invalid input like any other unparsable body, in the one error style
            return error(422, "invalid input: body could not be parsed (nested too deeply?)",
                         {"_": "body could not be parsed"})
        return error(exc.status_code, str(exc.detail), headers=exc.headers)

    @app.exception_handler(InputError)
    async def _input_error(request: Request, exc: InputError) -> JSONResponse:
        return error(422, f"invalid input: {exc}", exc.errors)

    auth.install_guard(app, ctx, bound=host, allowed_hosts=allowed_hosts)
    for make_router in ROUTERS:
        app.include_router(make_router(ctx))
    return app


# -- serving --------------------------------------------------------------------------------------
class _Server(uvicorn.Server):
    """uvicorn inside someone else's loop: leave the process's signal handlers alone."""

    @contextlib.contextmanager
    def capture_signals(self) -> Iterator[None]:
        yield


@dataclasses.dataclass
class ServedApp:
    """An app served by :func:`serve_app`: ``url`` to open it, ``stop_serving()`` to end the server."""

    host: str
    port: int
    password: str | None
    app: FastAPI
    _server: _Server
    _task: asyncio.Task[None]

    @property
    def url(self) -> str:
        host = f"[{self.host}]" if ":" in self.host else self.host
        if host in ("0.0.0.0", "[::]"):
            host = "127.0.0.1"
        return f"http://{host}:{self.port}/"

    async def stop_serving(self) -> None:
        self._server.should_exit = True
        with contextlib.suppress(asyncio.CancelledError):
            try:
                await asyncio.wait_for(asyncio.shield(self._task), timeout=5.0)
            except asyncio.TimeoutError:  # before Python 3.11 not the builtin TimeoutError
                self._task.cancel()


@dataclasses.dataclass
class WebHandle(ServedApp):
    """A running web interface: ``url`` to open, ``close()`` to stop it."""

    async def close(self) -> None:
        ctx: WebContext = self.app.state.ctx
        ctx.closing.set()
        await self.stop_serving()
        ctx.bridge.close()


def _bind(host: str, port: int) -> socket.socket:
    family, kind, proto, _, addr = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM,
                                                      flags=socket.AI_PASSIVE)[0]
    sock = socket.socket(family, kind, proto)
    try:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        sock.bind(addr)
    except OSError:
        sock.close()
        raise
    sock.set_inheritable(True)
    return sock


async def serve_app(app: Any, host: str, port: int, *, ssl_certfile: str | None = None,
                    ssl_keyfile: str | None = None, max_connections: int = 64, idle_timeout: float | None = None,
                    requests_per_connection: int | None = 100, request_rate: float | None = REQUEST_RATE,
                    request_burst: int = REQUEST_BURST) -> tuple[_Server, asyncio.Task[None], int]:
    """Serve the ASGI ``app`` on the running loop with the web interface's connection limits and
    per-client request rate (the options of :func:`serve_web`); (server, its task, the bound port).
    The Commander (``wsg commander``) is served the same way."""
    from ..server.conncap import capped_http_protocol
    from ..server.ratelimit import RequestRate

    sock = _bind(host, port)  # bind here: errors raise OSError instead of uvicorn's sys.exit
    real_port = int(sock.getsockname()[1])
    config = uvicorn.Config(
        app, host=host, port=real_port, log_level="warning", ws="websockets-sansio", lifespan="off",
        timeout_graceful_shutdown=2, ssl_certfile=ssl_certfile, ssl_keyfile=ssl_keyfile,
        ws_ping_interval=None, ws_max_size=live.WS_MAX_MESSAGE, server_header=False, http=capped_http_protocol(
            max_connections, idle_timeout, requests_per_connection,
            RequestRate(request_rate, request_burst) if request_rate else None),
    )
    server = _Server(config)
    task = asyncio.create_task(server.serve(sockets=[sock]), name=f"pywsg-web-{host}:{real_port}")
    while not server.started:
        if task.done():
            sock.close()
            raise OSError(f"web server could not start on {host}:{real_port}") from task.exception()
        await asyncio.sleep(0.01)
    return server, task, real_port


async def serve_web(gripper: Any, host: str, port: int, *, password: str | None = None, fieldbus: Any = None,
                    sim_info: Any = None, settings_path: str | Path | None = None,
                    ssl_certfile: str | None = None, ssl_keyfile: str | None = None,
                    allowed_hosts: Sequence[str] = (), max_connections: int = 64,
                    idle_timeout: float | None = None, requests_per_connection: int | None = 100,
                    request_rate: float | None = REQUEST_RATE, request_burst: int = REQUEST_BURST) -> WebHandle:
    """Start the web interface on the running loop; port 0 picks a free port (``handle.port``).

    Bound to a non-loopback address without a ``password``, one is generated and printed once to
    stderr (also ``handle.password``). ``fieldbus``: the FieldbusController whose register images the
    Fieldbus Monitor shows. ``sim_info``: what the simulator serves (interfaces and ports), shown
    under Settings → Command Interface. ``settings_path``: where changed settings are saved
    (default: ``gripper.settings_path`` when present). ``ssl_certfile``/``ssl_keyfile``: serve HTTPS.
    ``allowed_hosts``: names besides the bound address, localhost, 127.0.0.1 and [::1] that the
    ``Host`` header may carry (e.g. ``["gripper.cell4.local"]``); others get 400 (DNS rebinding).
    ``max_connections``: open HTTP/WebSocket connections at a time; more are refused; one without data
    either way for ``idle_timeout`` s is closed (None: never). ``requests_per_connection``: the
    keep-alive budget; the last allowed request is answered with ``Connection: close`` and what was
    pipelined after it is dropped (None: no limit). ``request_rate`` (requests/s, None: no limit) and
    ``request_burst``: the per-client rate limit (a token bucket per client address); a request over
    it is answered ``429 Too Many Requests`` with ``Retry-After`` before the app sees it.
    """
    loopback = is_loopback_host(host)
    if not loopback and password is None:
        password = secrets.token_urlsafe(12)
        print(f"wsg web interface on {host}:{port or '?'}: password {password}", file=sys.stderr, flush=True)
    if password is not None and (not password or len(password) > 256):
        raise ValueError("password must be 1..256 characters")
    app = create_app(gripper, loopback=loopback, password=password, fieldbus=fieldbus, sim_info=sim_info,
                     settings_path=settings_path, host=host, allowed_hosts=allowed_hosts)
    try:
        server, task, real_port = await serve_app(
            app, host, port, ssl_certfile=ssl_certfile, ssl_keyfile=ssl_keyfile, max_connections=max_connections,
            idle_timeout=idle_timeout, requests_per_connection=requests_per_connection,
            request_rate=request_rate, request_burst=request_burst)
    except OSError:
        app.state.ctx.bridge.close()
        raise
    log.info("web interface on %s:%d", host, real_port)
    return WebHandle(host=host, port=real_port, password=password, app=app, _server=server, _task=task)


__all__ = ["ServedApp", "WebHandle", "create_app", "serve_app", "serve_web"]
