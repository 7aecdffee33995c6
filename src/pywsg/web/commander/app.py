"""The Commander's web app: one page, its JSON API and its live WebSocket, behind the web interface's guard.

Routes (reads open on a loopback bind; every change needs the session's CSRF token, as in the web
interface: ``auth.install_guard``; the same connection limits and request rate: ``app.serve_app``):

- ``GET /``: the page; ``GET /api/csrf``: a fresh token
- ``GET /api/ports``: serial ports (pyserial's ``list_ports``); ``GET /api/commands``: the predefined commands
- ``POST /api/connect`` ``{"url"}``, ``POST /api/disconnect``
- ``GET /api/editor?id=&payload=``: the Custom Command Editor's live decoding (nothing is sent)
- ``POST /api/send`` ``{"id", "payload"}``: send the editor's packet
- ``POST /api/command/{key}`` ``{values}``: a predefined command (motions answer at E_CMD_PENDING)
- ``GET /api/log.jsonl``, ``GET /api/log.pcapng``: the Communication Log saved; ``POST /api/log/clear``
- ``WS /ws``: ``{"connection", "state", "log", "results"}`` when they change (at most 20 Hz)
"""

from __future__ import annotations

import asyncio
import contextlib
import dataclasses
import json
import secrets
import sys
import time
from html import escape
from typing import Any

from fastapi import APIRouter, Body, FastAPI, Request, WebSocket
from fastapi.exceptions import RequestValidationError
from fastapi.responses import HTMLResponse, JSONResponse, Response
from fastapi.staticfiles import StaticFiles
from starlette.exceptions import HTTPException as StarletteHTTPException

from ... import __version__
from .. import auth
from ..app import STATIC, ServedApp, serve_app
from ..context import error
from ..live import _int, _wait_closed, accept_live  # the web interface's WebSocket helpers
from ..pages import template
from ..security import Auth, WebSession, is_loopback_host
from .commands import catalog_json
from .export import to_jsonl, to_pcapng
from .session import CommandError, CommanderSession, preview

UPDATE_PERIOD_S = 0.05  # the WebSocket sends at most this often (s) when something changed
HEARTBEAT_S = 1.0  # and at least this often, so a page sees that the Commander itself is alive
MAX_PAGES = 16  # WebSocket clients at a time


@dataclasses.dataclass
class CommanderContext:
    """What the routes share: the session store (the guard's) and the gripper connection."""

    auth: Auth
    session: CommanderSession
    url: str = ""  # the --url given: the Connect dialog's first suggestion


def serial_ports() -> list[dict[str, str]]:
    """The serial ports pyserial finds (device, description); pseudo-terminals are typed in."""
    try:
        from serial.tools import list_ports
    except ImportError:  # pyserial is a dependency; be kind to a broken install anyway
        return []
    return [{"device": p.device, "description": p.description or ""} for p in sorted(list_ports.comports())]


def _failure(exc: CommandError) -> JSONResponse:
    body: dict[str, Any] = {"detail": str(exc), "errors": exc.errors}
    if exc.start is not None:
        body.update(start=exc.start, end=exc.end)
    return JSONResponse(body, status_code=exc.status)


def create_commander_app(session: CommanderSession, *, loopback: bool = True, password: str | None = None,
                         host: str | None = None, url: str = "") -> FastAPI:
    """The Commander's ASGI app over ``session``."""
    ctx = CommanderContext(auth=Auth(loopback=loopback, password=password), session=session, url=url)
    app = FastAPI(title="pywsg Commander", version=__version__, docs_url=None, redoc_url=None, openapi_url=None)
    app.state.ctx = ctx
    app.mount("/static", StaticFiles(directory=STATIC), name="static")

    @app.exception_handler(RequestValidationError)
    async def _invalid(request: Request, exc: RequestValidationError) -> JSONResponse:
        return error(422, "invalid input: " + "; ".join(str(e.get("msg", "")) for e in exc.errors()))

    @app.exception_handler(StarletteHTTPException)
    async def _http_error(request: Request, exc: StarletteHTTPException) -> Response:
        return error(exc.status_code, str(exc.detail), headers=exc.headers)

    auth.install_guard(app, ctx, bound=host)
    app.include_router(auth.router(ctx))
    app.include_router(router(ctx))
    return app


def router(ctx: CommanderContext) -> APIRouter:
    r = APIRouter()
    session = ctx.session

    @r.get("/", response_class=HTMLResponse, include_in_schema=False)
    async def page(request: Request) -> HTMLResponse:
        s: WebSession = request.state.websession
        body = template("commander.html").safe_substitute(
            csrf=escape(s.csrf), version=escape(__version__), url=escape(ctx.url or session.url or ""),
            can_write="true" if ctx.auth.may_write(s) else "false",
            commands=escape(json.dumps(catalog_json())))
        return HTMLResponse(body, headers={"Cache-Control": "no-store"})

    @r.get("/api/csrf")
    async def csrf(request: Request) -> dict[str, Any]:
        s: WebSession = request.state.websession
        return {"token": s.csrf, "can_write": ctx.auth.may_write(s)}

    @r.get("/api/ports")
    async def ports() -> dict[str, Any]:
        return {"ports": await asyncio.get_running_loop().run_in_executor(None, serial_ports)}

    @r.get("/api/commands")
    async def commands() -> list[dict[str, Any]]:
        return catalog_json()

    @r.get("/api/state")
    async def state() -> dict[str, Any]:
        return {"connection": session.connection(), "state": session.state,
                "results": list(session.results)[-20:]}

    @r.post("/api/connect")
    async def connect(body: dict[str, Any] = Body(...)) -> Response:  # noqa: B008 - FastAPI's idiom
        url = body.get("url")
        if not isinstance(url, str) or not url.strip():
            return error(422, "invalid input: url: give the gripper's address", {"url": "required"})
        try:
            return JSONResponse(await session.connect(url.strip()))
        except CommandError as exc:
            return _failure(exc)

    @r.post("/api/disconnect")
    async def disconnect() -> dict[str, Any]:
        await session.disconnect()
        return session.connection()

    @r.get("/api/editor")
    async def editor(id: str = "", payload: str = "") -> dict[str, Any]:
        return preview(id[:64], payload[:4096])

    @r.post("/api/send")
    async def send(body: dict[str, Any] = Body(...)) -> Response:  # noqa: B008
        cid, payload = body.get("id", ""), body.get("payload", "")
        if not isinstance(cid, str) or not isinstance(payload, str):
            return error(422, "invalid input: id and payload are text", {"_": "text"})
        try:
            return JSONResponse(await session.send_custom(cid, payload))
        except CommandError as exc:
            return _failure(exc)

    @r.post("/api/command/{key}")
    async def command(key: str, body: dict[str, Any] = Body(default={})) -> Response:  # noqa: B008
        try:
            result = await session.run(key, body)
        except CommandError as exc:
            return _failure(exc)
        return JSONResponse(result, status_code=202 if not result["final"] else 200)

    @r.post("/api/log/clear")
    async def clear() -> dict[str, Any]:
        session.clear_log()
        return {"ok": True}

    def _download(data: bytes | str, kind: str, media: str) -> Response:
        name = time.strftime("wsg-commander-%Y%m%d-%H%M%S") + "." + kind
        return Response(data, media_type=media, headers={"Content-Disposition": f'attachment; filename="{name}"',
                                                          "Cache-Control": "no-store"})

    @r.get("/api/log.jsonl")
    async def log_jsonl() -> Response:
        return _download(to_jsonl(session.entries()), "jsonl", "application/x-ndjson")

    @r.get("/api/log.pcapng")
    async def log_pcapng() -> Response:
        scheme = (session.url or "tcp:").split(":", 1)[0]
        return _download(to_pcapng(session.entries(), scheme), "pcapng", "application/octet-stream")

    @r.websocket("/ws")
    async def live(websocket: WebSocket) -> None:
        if not await accept_live(websocket, ctx.auth, session.pages >= MAX_PAGES, "too many Commander pages"):
            return
        session.page_opened()
        closed = asyncio.create_task(_wait_closed(websocket))
        q = websocket.query_params
        log_after = _int(q.get("log"), max(0, session.log_seq - 200))
        results_after = _int(q.get("results"), session.result_seq)
        conn_seen = state_seen = -1
        last_sent = 0.0
        try:
            while not closed.done():
                msg: dict[str, Any] = {"type": "update", "t": time.time()}
                if session.conn_seq != conn_seen:
                    msg["connection"] = session.connection()
                    conn_seen = session.conn_seq
                if session.state_seq != state_seen:
                    msg["state"] = session.state
                    state_seen = session.state_seq
                rows = session.log_after(log_after)
                if rows:
                    msg["log"] = rows
                    log_after = rows[-1]["seq"]
                results = session.results_after(results_after)
                if results:
                    msg["results"] = results
                    results_after = results[-1]["seq"]
                now = time.monotonic()
                if len(msg) > 2 or now - last_sent >= HEARTBEAT_S:
                    await websocket.send_text(json.dumps(msg, allow_nan=False))
                    last_sent = now
                await asyncio.wait([closed], timeout=UPDATE_PERIOD_S)  # at most 20 messages a second
        except Exception:  # the page went away mid-send
            pass
        finally:
            closed.cancel()
            session.page_closed()
            with contextlib.suppress(Exception):
                await websocket.close()

    return r


@dataclasses.dataclass
class CommanderHandle(ServedApp):
    """A running Commander: ``url`` to open, ``close()`` to stop it (disconnecting the gripper first)."""

    session: CommanderSession | None = None

    async def close(self) -> None:
        if self.session is not None:
            await self.session.close()
        await self.stop_serving()


async def serve_commander(host: str = "127.0.0.1", port: int = 0, *, url: str = "", connect: bool = False,
                          password: str | None = None, grace: float = 1.0, timeout: float = 3.0,
                          session: CommanderSession | None = None) -> CommanderHandle:
    """Start the Commander on the running loop (port 0: any free port, ``handle.port``).

    ``url``: the gripper the Connect dialog suggests (``connect``: connect to it at once). Bound to a
    non-loopback address without a ``password`` one is generated and printed once to stderr, as for
    the web interface. ``grace``: seconds after the last page closed before the gripper is
    disconnected (07h over TCP); ``timeout``: seconds to wait for each reply.
    """
    loopback = is_loopback_host(host)
    if not loopback and password is None:
        password = secrets.token_urlsafe(12)
        print(f"wsg commander on {host}:{port or '?'}: password {password}", file=sys.stderr, flush=True)
    session = session or CommanderSession(grace=grace, timeout=timeout)
    app = create_commander_app(session, loopback=loopback, password=password, host=host, url=url)
    server, task, real_port = await serve_app(app, host, port)
    handle = CommanderHandle(host, real_port, password, app, server, task, session)
    if connect and url:
        try:
            await session.connect(url)
        except CommandError as exc:
            print(f"wsg commander: {exc}", file=sys.stderr, flush=True)
    return handle


__all__ = ["CommanderContext", "CommanderHandle", "create_commander_app", "serial_ports", "serve_commander"]
