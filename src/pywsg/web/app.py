"""The virtual gripper's web interface (issue 6): pages, JSON API and a live WebSocket.

``serve_web(gripper, host, port)`` starts it on the running asyncio loop (what ``wsg sim --web-port``
does); ``create_app(...)`` gives the ASGI app alone. Motion and stop requests go through the binary
protocol: the web interface opens its own device session (``"web"``) and sends ordinary request
frames, so it obeys exactly the rules a TCP client meets. Settings go through
``gripper.apply_settings`` and are saved to the settings file when one is known; fault injection
calls ``gripper.faults``. Units everywhere: mm, mm/s, mm/s², N, °C.

Pages: ``/`` Control Panel, ``/settings/interface``, ``/settings/motion``, ``/diagnosis/log``,
``/diagnosis/fieldbus``, ``/simulation``, ``/help``; API under ``/api``; live data on ``/ws``.
See docs/web.md for the API and the security rules (``security.py``).
"""

from __future__ import annotations

import asyncio
import contextlib
import dataclasses
import json
import logging
import re
import secrets
import socket
import sys
import time
from collections import deque
from collections.abc import Awaitable, Callable, Iterator, Mapping
from html import escape
from pathlib import Path
from string import Template
from typing import Any, Literal
from urllib.parse import parse_qs, quote, urlsplit

import uvicorn
from fastapi import FastAPI, Request, WebSocket
from fastapi.exceptions import RequestValidationError
from fastapi.responses import HTMLResponse, JSONResponse, PlainTextResponse, RedirectResponse, Response
from fastapi.staticfiles import StaticFiles
from pydantic import BaseModel, ConfigDict, Field

from .. import __version__
from ..protocol import CATALOG, Command, DeviceType, Frame, HomingDirection, Status
from .fieldbus_view import fieldbus_view
from .reference import catalog_json, command_reference_html
from .security import COOKIE_NAME, CSRF_FIELD, CSRF_HEADER, Auth, WebSession, is_loopback_host
from .views import coerce_setting, field_of_error, jsonable, settings_schema, state_view

log = logging.getLogger(__name__)

HERE = Path(__file__).resolve().parent
STATIC = HERE / "static"
TEMPLATES = HERE / "templates"
PROJECT_DOCS = HERE.parents[2] / "docs"  # source checkout only; the Help page says when missing
UPDATE_PERIOD_S = 0.05  # 20 Hz WebSocket updates
MAX_BODY = 64 * 1024
MAX_LIVE_CLIENTS = 32  # WebSocket clients per interface: each costs a snapshot every 50 ms
SAFE_METHODS = frozenset({"GET", "HEAD", "OPTIONS"})


# -- request bodies (strict: JSON types must match; out-of-range values are 422) -------------------
class _Body(BaseModel):
    model_config = ConfigDict(strict=True, extra="forbid")


class HomeBody(_Body):
    direction: Literal["default", "positive", "negative"] = "default"


class MoveBody(_Body):
    width: float = Field(ge=0, allow_inf_nan=False, description="opening width, mm")
    speed: float = Field(gt=0, allow_inf_nan=False, description="mm/s")
    relative: bool = False
    stop_on_block: bool = False


class GripBody(_Body):
    width: float = Field(ge=0, allow_inf_nan=False, description="nominal part width, mm")
    speed: float = Field(gt=0, allow_inf_nan=False, description="mm/s")
    force: float | None = Field(default=None, gt=0, allow_inf_nan=False, description="force limit, N")


class ReleaseBody(_Body):
    width: float = Field(ge=0, allow_inf_nan=False, description="opening width, mm")
    speed: float = Field(gt=0, allow_inf_nan=False, description="mm/s")


class PartBody(_Body):
    width: float = Field(gt=0, allow_inf_nan=False, description="part width, mm")
    stiffness: float | None = Field(default=None, gt=0, allow_inf_nan=False, description="N/mm")


class BlockBody(_Body):
    width: float = Field(ge=0, allow_inf_nan=False, description="width where the fingers block, mm")


class HeatBody(_Body):
    delta_c: float = Field(ge=-200, le=200, allow_inf_nan=False, description="temperature change, °C")


class FaultBody(_Body):
    kind: Literal["power", "current", "finger"]
    on: bool
    finger: Literal[1, 2] = 1


class InputError(Exception):
    """A value the device cannot take: 422 with a message per field."""

    def __init__(self, errors: dict[str, str]) -> None:
        super().__init__("; ".join(f"{k}: {v}" for k, v in errors.items()))
        self.errors = errors


def _error(status: int, detail: str, errors: Mapping[str, str] | None = None) -> JSONResponse:
    body: dict[str, Any] = {"detail": detail}
    if errors is not None:
        body["errors"] = dict(errors)
    return JSONResponse(body, status_code=status)


# -- the device side ------------------------------------------------------------------------------
class CommandBridge:
    """The web interface's own device session: request frames in, status codes out."""

    def __init__(self, gripper: Any) -> None:
        self.gripper = gripper
        self.results: deque[dict[str, Any]] = deque(maxlen=100)
        self.seq = 0
        self.session = gripper.open_session("web", peer="web interface", deliver=self._deliver)

    def _record(self, command_id: int, status: Status | int, final: bool) -> dict[str, Any]:
        self.seq += 1
        name = Status(status).name if isinstance(status, Status) else f"status {int(status)}"
        entry = {"seq": self.seq, "time": time.time(), "command": CATALOG[command_id].name
                 if command_id in CATALOG else f"{command_id:02X}h", "status": name, "final": final}
        self.results.append(entry)
        return entry

    def _deliver(self, frame: Frame) -> None:
        """Deferred frames of this session: final replies of motions started here."""
        if len(frame.payload) >= 2:
            self._record(frame.command_id, frame.status, True)

    def send(self, command: Command, *, record: bool = True, **values: Any) -> tuple[Status | int, dict[str, Any]]:
        """Send one request; (status of the immediate reply, decoded reply values).

        ``record``: list it under the Control Panel's command results (not for internal queries).
        """
        spec = CATALOG[command]
        frame = Frame(int(command), spec.encode_request(values))
        replies = self.gripper.handle_frame(self.session, frame)
        answer: tuple[Status | int, dict[str, Any]] | None = None
        for reply in replies:
            if reply.command_id == int(command) and answer is None:
                status, decoded = spec.decode_reply(reply.payload)
                if record:
                    self._record(int(command), status, status != Status.E_CMD_PENDING)
                answer = status, dict(decoded)
            else:  # e.g. Stop: the aborted motion's final frame comes with 22h's own reply
                self._deliver(reply)
        if answer is None:
            raise RuntimeError(f"no reply to {spec.label}")
        return answer

    def limits(self) -> dict[str, float]:
        """53h Get System Limits: stroke mm, speeds mm/s, accelerations mm/s², forces N."""
        status, values = self.send(Command.GET_SYSTEM_LIMITS, record=False)
        if status != Status.E_SUCCESS:
            return {}
        return {k: float(v) for k, v in values.items() if isinstance(v, int | float)}

    def device_type(self) -> DeviceType | None:
        status, values = self.send(Command.GET_SYSTEM_INFO, record=False)
        t = values.get("type")
        return t if status == Status.E_SUCCESS and isinstance(t, DeviceType) else None

    def close(self) -> None:
        with contextlib.suppress(Exception):
            self.gripper.close_session(self.session)


class LogFeed:
    """The device's system log, numbered for incremental reads (``after=seq``)."""

    def __init__(self, system_log: Any, clock: Callable[[], float] | None = None, size: int = 2000) -> None:
        self.entries: deque[dict[str, Any]] = deque(maxlen=size)
        self.seq = 0
        self.clock = clock
        if system_log is None:
            return
        for entry in _existing_entries(system_log):
            self.add(entry)
        add_listener = getattr(system_log, "add_listener", None)
        if callable(add_listener):
            add_listener(self.add)

    def add(self, entry: Any) -> None:
        self.seq += 1
        data = jsonable(entry) if dataclasses.is_dataclass(entry) else {}
        for name in ("time", "level", "message"):
            if name not in data:
                data[name] = jsonable(getattr(entry, name, "" if name != "time" else None))
        if not data.get("message"):
            data["message"] = str(entry)
        data["seq"] = self.seq
        # entry times are device-clock seconds; the page shows wall-clock time
        t = data.get("time")
        wall = time.time()
        if isinstance(t, int | float) and self.clock is not None:
            with contextlib.suppress(Exception):
                wall -= max(0.0, float(self.clock()) - t)
        data["wall_time"] = wall
        self.entries.append(data)

    def after(self, seq: int, limit: int = 500) -> list[dict[str, Any]]:
        out = [e for e in self.entries if e["seq"] > seq]
        return out[-limit:]


def _existing_entries(system_log: Any) -> list[Any]:
    for name in ("entries", "records", "items"):
        got = getattr(system_log, name, None)
        if callable(got):
            got = got()
        if got is not None:
            try:
                return list(got)
            except TypeError:
                pass
    try:
        return list(system_log)
    except TypeError:
        return []


@dataclasses.dataclass
class WebContext:
    gripper: Any
    auth: Auth
    bridge: CommandBridge
    log_feed: LogFeed
    fieldbus: Any = None
    sim_info: Any = None
    settings_path: Path | None = None
    closing: asyncio.Event = dataclasses.field(default_factory=asyncio.Event)
    live_clients: int = 0
    _cache: dict[str, tuple[float, Any]] = dataclasses.field(default_factory=dict)

    def cached(self, key: str, make: Callable[[], Any], max_age: float = UPDATE_PERIOD_S / 2) -> Any:
        """One computation per update period shared by all live clients (32 clients, one snapshot)."""
        now = time.monotonic()
        hit = self._cache.get(key)
        if hit is not None and now - hit[0] < max_age:
            return hit[1]
        value = make()
        self._cache[key] = (now, value)
        return value

    def model_name(self) -> str:
        try:
            t = self.bridge.device_type()
        except Exception:
            t = None
        if t is None or t == DeviceType.UNKNOWN:
            return "WSG"
        return re.sub(r"^([A-Z]+)(\d+)$", r"\1 \2", t.name)

    def state(self) -> dict[str, Any]:
        return state_view(self.gripper.snapshot())

    def has_faults(self) -> bool:
        return getattr(self.gripper, "faults", None) is not None


# -- pages ----------------------------------------------------------------------------------------
MENU: list[tuple[str, list[tuple[str, str]]]] = [
    ("Control Panel", [("/", "Control Panel")]),
    ("Settings", [("/settings/interface", "Command Interface"), ("/settings/motion", "Motion Configuration")]),
    ("Diagnosis", [("/diagnosis/log", "System Log"), ("/diagnosis/fieldbus", "Fieldbus Monitor")]),
    ("Simulation", [("/simulation", "Simulation")]),
    ("Help", [("/help", "Documentation")]),
]


def _template(name: str) -> Template:
    return Template((TEMPLATES / name).read_text(encoding="utf-8"))


def _nav(current: str) -> str:
    parts = []
    for title, items in MENU:
        active = any(href == current for href, _ in items)
        if len(items) == 1:
            href, _ = items[0]
            parts.append(f"<li class='{'active' if active else ''}'><a href='{href}'>{escape(title)}</a></li>")
            continue
        links = "".join(
            f"<li><a href='{href}' class='{'active' if href == current else ''}'>{escape(label)}</a></li>"
            for href, label in items
        )
        parts.append(f"<li class='menu {'active' if active else ''}'><span>{escape(title)}</span>"
                     f"<ul>{links}</ul></li>")
    return "<ul class='nav'>" + "".join(parts) + "</ul>"


def render_page(ctx: WebContext, request: Request, path: str, title: str, body_template: str, script: str,
                **extra: str) -> HTMLResponse:
    s: WebSession = request.state.websession
    body = _template(body_template).safe_substitute(**extra)
    if ctx.auth.login_possible:
        user = ("<form method='post' action='/logout' class='inline'>"
                f"<input type='hidden' name='{CSRF_FIELD}' value='{escape(s.csrf)}'>"
                "<button type='submit' id='logout'>Log out</button></form>") if s.authenticated else \
            f"<a href='/login?next={quote(path)}' id='login-link'>Log in</a>"
    else:
        user = "<span class='muted'>local access</span>"
    page = _template("base.html").safe_substitute(
        title=escape(title), model=escape(ctx.model_name()), nav=_nav(path), body=body, csrf=escape(s.csrf),
        user=user, script=escape(script), version=escape(__version__),
        can_write="true" if ctx.auth.may_write(s) else "false",
    )
    return HTMLResponse(page, headers={"Cache-Control": "no-store"})


def _doc_files() -> list[str]:
    if not PROJECT_DOCS.is_dir():
        return []
    return sorted(p.name for p in PROJECT_DOCS.glob("*.md") if p.is_file())


# -- the app --------------------------------------------------------------------------------------
def create_app(gripper: Any, *, loopback: bool = True, password: str | None = None, fieldbus: Any = None,
               sim_info: Any = None, settings_path: str | Path | None = None) -> FastAPI:
    """The ASGI app for ``gripper``. ``loopback``: whether it is bound to a loopback address only."""
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
        return _error(422, "invalid input: " + "; ".join(f"{k}: {v}" for k, v in errors.items()), errors)

    @app.exception_handler(InputError)
    async def _input_error(request: Request, exc: InputError) -> JSONResponse:
        return _error(422, f"invalid input: {exc}", exc.errors)

    @app.middleware("http")
    async def _guard(request: Request, call_next: Callable[[Request], Awaitable[Response]]) -> Response:
        s = ctx.auth.lookup(request.cookies.get(COOKIE_NAME))
        fresh = s is None
        if s is None:
            s = ctx.auth.create()
        request.state.websession = s
        response = await _check(request, s, call_next)
        current: WebSession = request.state.websession
        if fresh or current is not s:
            # Secure under TLS; on plain http a Secure cookie would never come back from another host
            response.set_cookie(COOKIE_NAME, current.id, httponly=True, samesite="strict", path="/",
                                secure=request.url.scheme == "https")
        response.headers.setdefault("X-Frame-Options", "DENY")
        response.headers.setdefault("X-Content-Type-Options", "nosniff")
        response.headers.setdefault(
            "Content-Security-Policy",
            "default-src 'self'; img-src 'self' data:; style-src 'self'; script-src 'self'; "
            "connect-src 'self' ws: wss:; frame-ancestors 'none'; form-action 'self'",
        )
        return response

    async def _check(request: Request, s: WebSession,
                     call_next: Callable[[Request], Awaitable[Response]]) -> Response:
        path = request.url.path
        public = path.startswith("/static/") or path == "/login"
        if not public and not ctx.auth.may_read(s):
            if path.startswith("/api/") or request.method not in SAFE_METHODS:
                return _error(401, "login required")
            return RedirectResponse("/login?next=" + quote(path), status_code=303)
        if request.method in SAFE_METHODS:
            return await call_next(request)
        length = request.headers.get("content-length")
        if length is not None and (not length.isdigit() or int(length) > MAX_BODY):
            return _error(413, f"request body larger than {MAX_BODY} bytes")
        if not _same_origin(request):
            return _error(403, "cross-origin request refused")
        if path in ("/login", "/logout"):  # form posts: token checked by the handler
            return await call_next(request)
        if not ctx.auth.may_write(s):
            return _error(401, "login required to change the gripper")
        if not ctx.auth.csrf_ok(s, request.headers.get(CSRF_HEADER)):
            return _error(403, f"missing or wrong CSRF token (send the {CSRF_HEADER} header)")
        return await call_next(request)

    _add_pages(app, ctx)
    _add_api(app, ctx)
    _add_websocket(app, ctx)
    return app


def _same_origin(request: Request | WebSocket) -> bool:
    """An Origin header, when the browser sends one, must name this server."""
    origin = request.headers.get("origin")
    if not origin or origin == "null":
        return origin is None
    host = request.headers.get("host", "")
    return urlsplit(origin).netloc.lower() == host.lower()


async def _form(request: Request) -> dict[str, str]:
    raw = (await request.body())[:MAX_BODY].decode("utf-8", "replace")
    return {k: v[0] for k, v in parse_qs(raw, keep_blank_values=True).items()}


def _add_pages(app: FastAPI, ctx: WebContext) -> None:
    pages = {
        "/": ("Control Panel", "control.html", "control"),
        "/settings/interface": ("Command Interface", "settings.html", "settings"),
        "/settings/motion": ("Motion Configuration", "settings.html", "settings"),
        "/diagnosis/log": ("System Log", "log.html", "log"),
        "/diagnosis/fieldbus": ("Fieldbus Monitor", "fieldbus.html", "fieldbus"),
        "/simulation": ("Simulation", "simulation.html", "simulation"),
    }

    def make(path: str, title: str, tpl: str, script: str) -> Callable[[Request], Awaitable[HTMLResponse]]:
        group = "interface" if path.endswith("interface") else "motion"

        async def page(request: Request) -> HTMLResponse:
            return render_page(ctx, request, path, title, tpl, script, group=group, heading=escape(title))

        return page

    for path, (title, tpl, script) in pages.items():
        app.add_api_route(path, make(path, title, tpl, script), methods=["GET"], response_class=HTMLResponse,
                          include_in_schema=False)

    @app.get("/help", response_class=HTMLResponse, include_in_schema=False)
    async def help_page(request: Request) -> HTMLResponse:
        files = _doc_files()
        docs = "".join(f"<li><a href='/docs/{escape(n)}'>{escape(n)}</a></li>" for n in files) or \
            "<li class='muted'>project docs are not installed with this copy (see the repository's docs/)</li>"
        return render_page(ctx, request, "/help", "Documentation", "help.html", "help", docs=docs,
                           reference=command_reference_html())

    @app.get("/docs/{name}", response_class=PlainTextResponse, include_in_schema=False)
    async def doc_file(name: str) -> Response:
        if name not in _doc_files():  # only listed files: no path traversal
            return _error(404, f"no document {name!r}")
        return PlainTextResponse((PROJECT_DOCS / name).read_text(encoding="utf-8"),
                                 media_type="text/markdown; charset=utf-8")

    @app.get("/login", response_class=HTMLResponse, include_in_schema=False)
    async def login_page(request: Request, next: str = "/", error: str = "") -> HTMLResponse:
        return _login_html(ctx, request, next, error)

    @app.post("/login", include_in_schema=False)
    async def login(request: Request) -> Response:
        s: WebSession = request.state.websession
        form = await _form(request)
        target = _safe_next(form.get("next", "/"))
        client = request.client.host if request.client else "?"
        if not ctx.auth.csrf_ok(s, form.get(CSRF_FIELD)):
            return _error(403, "missing or wrong CSRF token")
        if not ctx.auth.login_possible:
            return _error(400, "no password is set: this interface needs no login")
        if ctx.auth.throttled(client):
            return _error(429, "too many failed logins; wait a minute")
        fresh = ctx.auth.login(s, form.get("password", ""), client)
        if fresh is None:
            log.warning("web: failed login from %s", client)
            return _login_html(ctx, request, target, "Wrong password.", status=401)
        log.info("web: login from %s", client)
        request.state.websession = fresh
        return RedirectResponse(target, status_code=303)

    @app.post("/logout", include_in_schema=False)
    async def logout(request: Request) -> Response:
        s: WebSession = request.state.websession
        form = await _form(request)
        if not ctx.auth.csrf_ok(s, form.get(CSRF_FIELD) or request.headers.get(CSRF_HEADER)):
            return _error(403, "missing or wrong CSRF token")
        ctx.auth.drop(s)
        request.state.websession = ctx.auth.create()
        return RedirectResponse("/login" if not ctx.auth.loopback else "/", status_code=303)


def _safe_next(target: str) -> str:
    """Only local paths after login (no open redirect)."""
    if not target.startswith("/") or target.startswith("//") or "\\" in target:
        return "/"
    return target


def _login_html(ctx: WebContext, request: Request, target: str, error: str, status: int = 200) -> HTMLResponse:
    s: WebSession = request.state.websession
    body = _template("login.html").safe_substitute(
        csrf=escape(s.csrf), next=escape(_safe_next(target)), error=escape(error),
        note="" if ctx.auth.login_possible else "No password is set for this interface: no login needed.",
    )
    return HTMLResponse(body, status_code=status, headers={"Cache-Control": "no-store"})


def _command_result(command: Command, status: Status | int, values: Mapping[str, Any] | None = None
                    ) -> JSONResponse:
    """200 E_SUCCESS, 202 E_CMD_PENDING (final result follows on the WebSocket), 409 device refusal."""
    name = status.name if isinstance(status, Status) else f"status {int(status)}"
    body: dict[str, Any] = {
        "command": CATALOG[command].name, "status": name, "code": int(status),
        "message": status.description if isinstance(status, Status) else "unknown status code",
    }
    if values:
        body["values"] = jsonable(dict(values))
    if status == Status.E_SUCCESS:
        return JSONResponse(body)
    if status == Status.E_CMD_PENDING:
        return JSONResponse(body, status_code=202)
    body["detail"] = f"{CATALOG[command].name} refused by the device: {body['message']} ({name})"
    return JSONResponse(body, status_code=409)


def _check_range(errors: dict[str, str], name: str, value: float, low: float | None, high: float | None,
                 unit: str) -> None:
    if (low is not None and value < low) or (high is not None and value > high):
        lo = "" if low is None else f"{low:g}"
        hi = "" if high is None else f"{high:g}"
        errors[name] = f"must be between {lo} and {hi} {unit}".replace("between  and", "at most")


def _add_api(app: FastAPI, ctx: WebContext) -> None:
    bridge = ctx.bridge

    def motion_limits(width: float | None, speed: float | None, force: float | None = None,
                      relative: bool = False) -> None:
        lim = bridge.limits()
        errors: dict[str, str] = {}
        stroke = lim.get("stroke")
        if width is not None and stroke is not None:
            _check_range(errors, "width", width, -stroke if relative else 0.0, stroke, "mm")
        if speed is not None and "max_speed" in lim:
            _check_range(errors, "speed", speed, 0.0, lim["max_speed"], "mm/s")
        if force is not None and "ovr_force" in lim:
            _check_range(errors, "force", force, 0.0, max(lim["ovr_force"], lim.get("nom_force", 0.0)), "N")
        if errors:
            raise InputError(errors)

    @app.get("/api/csrf")
    async def csrf(request: Request) -> dict[str, Any]:
        """The session's CSRF token (same-origin pages and scripts only: no CORS)."""
        s: WebSession = request.state.websession
        return {"token": s.csrf, "authenticated": s.authenticated, "can_write": ctx.auth.may_write(s),
                "login_possible": ctx.auth.login_possible}

    @app.get("/api/state")
    async def state() -> dict[str, Any]:
        """Snapshot: width mm, speed mm/s, force N, temperature °C, flags, gripper state."""
        return ctx.state()

    @app.get("/api/info")
    async def info() -> dict[str, Any]:
        status, values = bridge.send(Command.GET_SYSTEM_INFO, record=False)
        return {"model": ctx.model_name(), "system_info": jsonable(values) if status == Status.E_SUCCESS else None,
                "limits": bridge.limits(), "sim": jsonable(ctx.sim_info), "version": __version__,
                "simulation": ctx.has_faults(), "fieldbus": ctx.fieldbus is not None,
                "settings_file": str(ctx.settings_path) if ctx.settings_path else None}

    @app.post("/api/stop")
    async def stop() -> JSONResponse:
        return _command_result(Command.STOP, bridge.send(Command.STOP)[0])

    @app.post("/api/fast-stop")
    async def fast_stop() -> JSONResponse:
        return _command_result(Command.FAST_STOP, bridge.send(Command.FAST_STOP)[0])

    @app.post("/api/ack")
    async def ack() -> JSONResponse:
        return _command_result(Command.ACK_FAST_STOP, bridge.send(Command.ACK_FAST_STOP, key="ack")[0])

    @app.post("/api/home")
    async def home(body: HomeBody | None = None) -> JSONResponse:
        direction = HomingDirection[(body.direction if body else "default").upper()]
        return _command_result(Command.HOMING, bridge.send(Command.HOMING, direction=int(direction))[0])

    @app.post("/api/move")
    async def move(body: MoveBody) -> JSONResponse:
        motion_limits(body.width, body.speed, relative=body.relative)
        flags = (1 if body.relative else 0) | (2 if body.stop_on_block else 0)
        status, _ = bridge.send(Command.PREPOSITION, flags=flags, width=body.width, speed=body.speed)
        return _command_result(Command.PREPOSITION, status)

    @app.post("/api/grip")
    async def grip(body: GripBody) -> JSONResponse:
        motion_limits(body.width, body.speed, body.force)
        if body.force is not None:
            status, _ = bridge.send(Command.SET_FORCE_LIMIT, force=body.force)
            if status != Status.E_SUCCESS:
                return _command_result(Command.SET_FORCE_LIMIT, status)
        status, _ = bridge.send(Command.GRIP_PART, width=body.width, speed=body.speed)
        return _command_result(Command.GRIP_PART, status)

    @app.post("/api/release")
    async def release(body: ReleaseBody) -> JSONResponse:
        motion_limits(body.width, body.speed)
        status, _ = bridge.send(Command.RELEASE_PART, width=body.width, speed=body.speed)
        return _command_result(Command.RELEASE_PART, status)

    @app.get("/api/results")
    async def results(after: int = 0) -> list[dict[str, Any]]:
        """Results of commands sent from the web interface (immediate and final)."""
        return [r for r in bridge.results if r["seq"] > after]

    # -- settings -------------------------------------------------------------------------------
    def settings_body() -> dict[str, Any]:
        current = ctx.gripper.settings
        return {"values": jsonable(current), "fields": settings_schema(current),
                "settings_file": str(ctx.settings_path) if ctx.settings_path else None,
                "interfaces": jsonable(ctx.sim_info)}

    @app.get("/api/settings")
    async def get_settings() -> dict[str, Any]:
        return settings_body()

    @app.post("/api/settings")
    async def post_settings(request: Request) -> Response:
        """Change some settings: a JSON object {name: value}. 422 names each refused field."""
        try:
            raw = json.loads(await request.body())
        except (ValueError, UnicodeDecodeError):
            return _error(422, "invalid input: body is not JSON", {"_": "body is not JSON"})
        if not isinstance(raw, dict) or not raw:
            return _error(422, "invalid input: expected a JSON object of settings",
                          {"_": "expected a JSON object {name: value}"})
        current = ctx.gripper.settings
        schema = {e["name"]: e for e in settings_schema(current)}
        changes: dict[str, Any] = {}
        errors: dict[str, str] = {}
        for name, value in raw.items():
            if name not in schema:
                errors[name] = "unknown setting"
                continue
            try:
                changes[name] = coerce_setting(schema[name], value, getattr(current, name))
            except ValueError as exc:
                errors[name] = str(exc)
        if errors:
            return _error(422, "invalid input: " + "; ".join(f"{k}: {v}" for k, v in errors.items()), errors)
        try:
            new = dataclasses.replace(current, **changes)
            ctx.gripper.apply_settings(new)
        except (ValueError, TypeError) as exc:
            field, reason = field_of_error(str(exc), list(schema))
            return _error(422, f"invalid input: {exc}", {field: reason})
        saved = None
        if ctx.settings_path is not None:
            try:
                ctx.gripper.settings.save(ctx.settings_path)
                saved = str(ctx.settings_path)
            except OSError as exc:
                return _error(500, f"applied, but not saved to {ctx.settings_path}: {exc}")
        log.info("web: settings changed: %s", ", ".join(changes))
        body = settings_body()
        body["changed"] = sorted(changes)
        body["saved"] = saved
        return JSONResponse(body)

    # -- diagnosis ------------------------------------------------------------------------------
    @app.get("/api/log")
    async def get_log(after: int = 0, limit: int = 500) -> Response:
        if after < 0 or not 1 <= limit <= 2000:
            return _error(422, "invalid input: after >= 0, 1 <= limit <= 2000",
                          {"after" if after < 0 else "limit": "out of range"})
        return JSONResponse({"entries": ctx.log_feed.after(after, limit), "last": ctx.log_feed.seq})

    @app.get("/api/fieldbus")
    async def get_fieldbus() -> dict[str, Any]:
        return fieldbus_view(ctx.fieldbus)

    @app.get("/api/commands")
    async def commands() -> list[dict[str, Any]]:
        return catalog_json()

    # -- simulation (fault injection) -----------------------------------------------------------
    def faults() -> Any:
        f = getattr(ctx.gripper, "faults", None)
        if f is None:
            raise InputError({"_": "this gripper has no fault injection (not a virtual gripper)"})
        return f

    def inject(fn: Callable[..., Any], *args: Any, **kwargs: Any) -> None:
        try:
            fn(*args, **kwargs)
        except ValueError as exc:  # the device names the field: "width: must be ..."
            field, reason = field_of_error(str(exc), ["width", "stiffness", "delta_c", "finger"])
            raise InputError({field: reason}) from None

    def done(action: str) -> dict[str, Any]:
        log.info("web: simulation: %s", action)
        return {"ok": True, "action": action, "state": ctx.state()}

    @app.post("/api/sim/part")
    async def place_part(body: PartBody) -> dict[str, Any]:
        motion_limits(body.width, None)
        if body.stiffness is None:
            inject(faults().place_part, body.width)
        else:
            inject(faults().place_part, body.width, stiffness=body.stiffness)
        return done(f"part of {body.width:g} mm placed")

    @app.delete("/api/sim/part")
    async def remove_part() -> dict[str, Any]:
        faults().remove_part()
        return done("part removed")

    @app.post("/api/sim/block")
    async def block(body: BlockBody) -> dict[str, Any]:
        motion_limits(body.width, None)
        inject(faults().block_at, body.width)
        return done(f"fingers blocked at {body.width:g} mm")

    @app.delete("/api/sim/block")
    async def unblock() -> dict[str, Any]:
        faults().unblock()
        return done("fingers unblocked")

    @app.post("/api/sim/heat")
    async def heat(body: HeatBody) -> dict[str, Any]:
        inject(faults().heat, body.delta_c)
        return done(f"temperature changed by {body.delta_c:+g} °C")

    @app.post("/api/sim/fault")
    async def fault(body: FaultBody) -> dict[str, Any]:
        f = faults()
        if body.kind == "power":
            inject(f.power_fault, body.on)
        elif body.kind == "current":
            inject(f.current_fault, body.on)
        else:
            inject(f.finger_fault, body.finger - 1, body.on)  # the device counts fingers from 0
        which = f"finger {body.finger} " if body.kind == "finger" else ""
        return done(f"{which}{body.kind} fault {'on' if body.on else 'off'}")


def _add_websocket(app: FastAPI, ctx: WebContext) -> None:
    @app.websocket("/ws")
    async def live(websocket: WebSocket) -> None:
        """~20 Hz: state, new log entries, new command results, and (``?fieldbus=1``) the registers."""
        s = ctx.auth.lookup(websocket.cookies.get(COOKIE_NAME))
        if not ctx.auth.may_read(s) or not _same_origin(websocket):
            await websocket.close(code=1008)
            return
        await websocket.accept()
        if ctx.live_clients >= MAX_LIVE_CLIENTS:
            await websocket.close(code=1013, reason="too many live clients")  # try again later
            return
        ctx.live_clients += 1
        q = websocket.query_params
        want_fieldbus = q.get("fieldbus") == "1"
        log_after = _int(q.get("log"), ctx.log_feed.seq)
        results_after = _int(q.get("results"), ctx.bridge.seq)
        closed = asyncio.create_task(_wait_closed(websocket))
        try:
            while not ctx.closing.is_set() and not closed.done():
                msg: dict[str, Any] = {"type": "update", "t": time.time(), "state": ctx.cached("state", ctx.state)}
                entries = ctx.log_feed.after(log_after)
                if entries:
                    msg["log"] = entries
                    log_after = entries[-1]["seq"]
                results = [r for r in ctx.bridge.results if r["seq"] > results_after]
                if results:
                    msg["results"] = results
                    results_after = results[-1]["seq"]
                if want_fieldbus:
                    msg["fieldbus"] = ctx.cached("fieldbus", lambda: fieldbus_view(ctx.fieldbus))
                await websocket.send_text(json.dumps(msg, allow_nan=False))
                await asyncio.wait([closed], timeout=UPDATE_PERIOD_S)
        except Exception:  # the client went away mid-send: nothing to clean up but the task
            pass
        finally:
            ctx.live_clients -= 1
            closed.cancel()
            with contextlib.suppress(Exception):
                await websocket.close()


async def _wait_closed(websocket: WebSocket) -> None:
    with contextlib.suppress(Exception):
        while True:
            message = await websocket.receive()
            if message.get("type") == "websocket.disconnect":
                return


def _int(text: str | None, default: int) -> int:
    try:
        return int(text) if text is not None else default
    except ValueError:
        return default


# -- serving --------------------------------------------------------------------------------------
class _Server(uvicorn.Server):
    """uvicorn inside someone else's loop: leave the process's signal handlers alone."""

    @contextlib.contextmanager
    def capture_signals(self) -> Iterator[None]:
        yield


@dataclasses.dataclass
class WebHandle:
    """A running web interface: ``url`` to open, ``close()`` to stop it."""

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

    async def close(self) -> None:
        ctx: WebContext = self.app.state.ctx
        ctx.closing.set()
        self._server.should_exit = True
        with contextlib.suppress(asyncio.CancelledError):
            try:
                await asyncio.wait_for(asyncio.shield(self._task), timeout=5.0)
            except TimeoutError:
                self._task.cancel()
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


async def serve_web(gripper: Any, host: str, port: int, *, password: str | None = None, fieldbus: Any = None,
                    sim_info: Any = None, settings_path: str | Path | None = None,
                    ssl_certfile: str | None = None, ssl_keyfile: str | None = None) -> WebHandle:
    """Start the web interface on the running loop; port 0 picks a free port (``handle.port``).

    Bound to a non-loopback address without a ``password``, one is generated and printed once to
    stderr (also ``handle.password``). ``fieldbus``: the FieldbusController whose register images the
    Fieldbus Monitor shows. ``sim_info``: what the simulator serves (interfaces and ports), shown
    under Settings → Command Interface. ``settings_path``: where changed settings are saved
    (default: ``gripper.settings_path`` when present). ``ssl_certfile``/``ssl_keyfile``: serve HTTPS.
    """
    loopback = is_loopback_host(host)
    if not loopback and password is None:
        password = secrets.token_urlsafe(12)
        print(f"wsg web interface on {host}:{port or '?'}: password {password}", file=sys.stderr, flush=True)
    if password is not None and (not password or len(password) > 256):
        raise ValueError("password must be 1..256 characters")
    app = create_app(gripper, loopback=loopback, password=password, fieldbus=fieldbus, sim_info=sim_info,
                     settings_path=settings_path)
    sock = _bind(host, port)  # bind here: errors raise OSError instead of uvicorn's sys.exit
    real_port = int(sock.getsockname()[1])
    config = uvicorn.Config(
        app, host=host, port=real_port, log_level="warning", ws="websockets-sansio", lifespan="off",
        timeout_graceful_shutdown=2, ssl_certfile=ssl_certfile, ssl_keyfile=ssl_keyfile,
        ws_ping_interval=None, server_header=False,
    )
    server = _Server(config)
    task = asyncio.create_task(server.serve(sockets=[sock]), name=f"pywsg-web-{host}:{real_port}")
    while not server.started:
        if task.done():
            app.state.ctx.bridge.close()
            sock.close()
            raise OSError(f"web interface could not start on {host}:{real_port}") from task.exception()
        await asyncio.sleep(0.01)
    log.info("web interface on %s:%d", host, real_port)
    return WebHandle(host=host, port=real_port, password=password, app=app, _server=server, _task=task)


__all__ = ["WebHandle", "create_app", "serve_web"]
