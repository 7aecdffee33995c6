"""Auth glue: the guards every request passes, and the login/logout routes.

The rules themselves (who may read, who may write, CSRF tokens, sessions) live in ``security.py``;
this module applies them to requests, outermost first:

- ``HostCheck``: the ``Host`` header must name this server (no DNS rebinding);
- ``BodyLimit``: a request body is cut off at ``MAX_BODY`` bytes while it streams (413), chunked or not;
- the guard: finds or creates the session cookie, answers 401/403/413 before a handler runs, and
  sets the security headers on every response.

Login and logout are form posts (the login page works without JavaScript).
"""

from __future__ import annotations

import ipaddress
import logging
from collections.abc import Iterable
from html import escape
from string import Template
from typing import Protocol
from urllib.parse import parse_qs, quote, urlsplit

from fastapi import APIRouter, FastAPI, HTTPException, Request, WebSocket
from fastapi.responses import HTMLResponse, RedirectResponse, Response
from starlette.datastructures import Headers, MutableHeaders
from starlette.middleware.trustedhost import TrustedHostMiddleware
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from . import health, world_api
from .context import MAX_BODY, error
from .pages import template
from .security import COOKIE_NAME, CSRF_FIELD, CSRF_HEADER, Auth, WebSession

log = logging.getLogger(__name__)

SAFE_METHODS = frozenset({"GET", "HEAD", "OPTIONS"})
CSP = ("default-src 'self'; img-src 'self' data:; style-src 'self'; script-src 'self'; "
       "connect-src 'self' ws: wss:; frame-ancestors 'none'; form-action 'self'")


def same_origin(request: Request | WebSocket) -> bool:
    """An Origin header, when the browser sends one, must name this server."""
    origin = request.headers.get("origin")
    if not origin or origin == "null":
        return origin is None
    host = request.headers.get("host", "")
    return urlsplit(origin).netloc.lower() == host.lower()


LOOPBACK_NAMES = ("localhost", "127.0.0.1", "::1")
WILDCARD_BINDS = ("", "0.0.0.0", "::")


def _host_name(host_header: str | None) -> str | None:
    """The name or address in a ``Host`` header, lower case, without port or brackets."""
    if not host_header:
        return None
    try:
        return urlsplit("//" + host_header).hostname
    except ValueError:
        return None


def _is_ip(name: str) -> bool:
    try:
        ipaddress.ip_address(name)
    except ValueError:
        return False
    return True


class HostCheck(TrustedHostMiddleware):
    """Starlette's TrustedHostMiddleware for the names this server answers to.

    Accepted: the bound address, ``localhost``, ``127.0.0.1``, ``[::1]`` and the configured names
    (``allowed_hosts``). A rebinding attacker's page reaches 127.0.0.1 under *his* name
    (``rebind.example``), so its requests are refused with 400 before any cookie or CSRF token is
    looked at. Bound to a wildcard address (0.0.0.0, ::) any IP address literal is accepted too:
    DNS cannot rebind an address, and the machine's own addresses are not known in advance.
    """

    def __init__(self, app: ASGIApp, *, bound: str | None, allowed_hosts: Iterable[str] = ()) -> None:
        names = {*LOOPBACK_NAMES, *(h.lower().strip("[]") for h in allowed_hosts)}
        bound_name = (bound or "").lower().strip("[]")
        self.any_ip = bound is None or bound_name in WILDCARD_BINDS
        if not self.any_ip:
            names.add(bound_name)
        # TrustedHostMiddleware keeps IPv6 literals in brackets
        super().__init__(app, allowed_hosts=sorted(f"[{n}]" if ":" in n else n for n in names),
                         www_redirect=False)

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if self.any_ip and scope["type"] in ("http", "websocket"):
            name = _host_name(Headers(scope=scope).get("host"))
            if name is not None and _is_ip(name):
                await self.app(scope, receive, send)
                return
        await super().__call__(scope, receive, send)


class BodyLimit:
    """Refuse a request body over ``limit`` bytes while it streams: 413, connection closed.

    The guard checks a declared Content-Length up front; a chunked body (or one longer than it
    claims) is counted here as the handler reads it, so no handler ever holds more than ``limit``
    bytes and the rest is never read from the socket.
    """

    def __init__(self, app: ASGIApp, limit: int = MAX_BODY) -> None:
        self.app = app
        self.limit = limit

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        seen = 0

        async def limited() -> Message:
            nonlocal seen
            message = await receive()
            if message["type"] == "http.request":
                seen += len(message.get("body", b""))
                if seen > self.limit:  # the route's exception handling turns this into the JSON 413
                    raise HTTPException(413, f"request body larger than {self.limit} bytes",
                                        headers={"Connection": "close"})
            return message

        await self.app(scope, limited, send)


class HasAuth(Protocol):
    """What the guard needs of an app's context: its session store (the web interface's
    ``WebContext``, the Commander's own)."""

    auth: Auth


class Guard:
    """The session, permission and CSRF check of every HTTP request, and the headers of every answer.

    A plain ASGI middleware rather than Starlette's ``BaseHTTPMiddleware`` (which runs each route in a
    task of its own and streams its answer back through a memory stream): the route's answer goes
    straight through, the headers added on the way.
    """

    def __init__(self, app: ASGIApp, ctx: HasAuth) -> None:
        self.app = app
        self.ctx = ctx

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        auth = self.ctx.auth
        request = Request(scope, receive)
        s = auth.lookup(request.cookies.get(COOKIE_NAME))
        fresh = s is None
        if s is None:
            s = auth.create()
        state = scope.setdefault("state", {})
        state["websession"] = s  # request.state.websession in the routes (login replaces it)

        async def send_with_headers(message: Message) -> None:
            if message["type"] == "http.response.start":
                headers = MutableHeaders(scope=message)
                current: WebSession = state["websession"]
                if fresh or current is not s:
                    # Secure under TLS; on plain http a Secure cookie would never come back from another host
                    cookie = Response()
                    cookie.set_cookie(COOKIE_NAME, current.id, httponly=True, samesite="strict", path="/",
                                      secure=request.url.scheme == "https")
                    headers.append("set-cookie", cookie.headers["set-cookie"])
                headers.setdefault("X-Frame-Options", "DENY")
                headers.setdefault("X-Content-Type-Options", "nosniff")
                headers.setdefault("Content-Security-Policy", CSP)
            await send(message)

        refusal = self._refusal(request, s)
        await (refusal or self.app)(scope, receive, send_with_headers)

    def _refusal(self, request: Request, s: WebSession) -> Response | None:
        """The answer to a request the route must not see, or None to let it through."""
        auth = self.ctx.auth
        path = request.url.path
        if path.startswith(world_api.PREFIX):  # scripts, not browsers: own access rules
            return world_api.guard(request, auth)
        public = path.startswith("/static/") or path in ("/login", health.PATH)
        if not public and not auth.may_read(s):
            if path.startswith("/api/") or request.method not in SAFE_METHODS:
                return error(401, "login required")
            return RedirectResponse("/login?next=" + quote(path), status_code=303)
        if request.method in SAFE_METHODS:
            return None
        length = request.headers.get("content-length")
        if length is not None and (not length.isdigit() or int(length) > MAX_BODY):
            return error(413, f"request body larger than {MAX_BODY} bytes")
        if not same_origin(request):
            return error(403, "cross-origin request refused")
        if path in ("/login", "/logout"):  # form posts: token checked by the handler
            return None
        if not auth.may_write(s):
            return error(401, "login required to change the gripper")
        if not auth.csrf_ok(s, request.headers.get(CSRF_HEADER)):
            return error(403, f"missing or wrong CSRF token (send the {CSRF_HEADER} header)")
        return None


def install_guard(app: FastAPI, ctx: HasAuth, *, bound: str | None = None,
                  allowed_hosts: Iterable[str] = ()) -> None:
    """The host check, the body limit, the session/permission/CSRF guard and the headers."""
    # Starlette runs the middleware added last first: HostCheck, the guard, then BodyLimit (inside
    # the guard, so that its 413 reaches the route's exception handling)
    app.add_middleware(BodyLimit, limit=MAX_BODY)
    app.add_middleware(Guard, ctx=ctx)
    app.add_middleware(HostCheck, bound=bound, allowed_hosts=tuple(allowed_hosts))  # outermost


async def _form(request: Request) -> dict[str, str]:
    raw = (await request.body()).decode("utf-8", "replace")  # at most MAX_BODY bytes: BodyLimit
    return {k: v[0] for k, v in parse_qs(raw, keep_blank_values=True).items()}


def safe_next(target: str) -> str:
    """Only local paths after login (no open redirect)."""
    if not target.startswith("/") or target.startswith("//") or "\\" in target:
        return "/"
    return target


_LOGIN_FORM = """<form method="post" action="/login" id="login-form">
  <h1>WSG Control Panel</h1>
  <input type="hidden" name="csrf_token" value="$csrf">
  <input type="hidden" name="next" value="$next">
  <label>Password <input type="password" name="password" id="password" autocomplete="current-password" required \
autofocus></label>
  <p class="error" id="login-error">$error</p>
  <button type="submit" id="login-submit">Log in</button>
</form>"""

# no password set (a loopback bind): nothing to log in to, so no password field, and a way back
_NO_LOGIN = """<h1>WSG Control Panel</h1>
<p id="login-note">No password is set for this interface: no login needed, every page is open from this computer.</p>
<p><a class="back" id="login-back" href="$next">Back to the interface</a></p>"""


def login_html(ctx: HasAuth, request: Request, target: str, error_text: str, status: int = 200) -> HTMLResponse:
    s: WebSession = request.state.websession
    content = Template(_LOGIN_FORM if ctx.auth.login_possible else _NO_LOGIN).safe_substitute(
        csrf=escape(s.csrf), next=escape(safe_next(target)), error=escape(error_text))
    body = template("login.html").safe_substitute(content=content)
    return HTMLResponse(body, status_code=status, headers={"Cache-Control": "no-store"})


def router(ctx: HasAuth) -> APIRouter:
    """GET/POST /login and POST /logout."""
    r = APIRouter(include_in_schema=False)

    @r.get("/login", response_class=HTMLResponse)
    async def login_page(request: Request, next: str = "/", error: str = "") -> HTMLResponse:
        return login_html(ctx, request, next, error)

    @r.post("/login")
    async def login(request: Request) -> Response:
        s: WebSession = request.state.websession
        form = await _form(request)
        target = safe_next(form.get("next", "/"))
        client = request.client.host if request.client else "?"
        # the login form is a page: its refusals are pages too (the JSON API answers JSON)
        if not ctx.auth.csrf_ok(s, form.get(CSRF_FIELD)):
            return login_html(ctx, request, target, "The login form had expired: please try again.", status=403)
        if not ctx.auth.login_possible:
            return error(400, "no password is set: this interface needs no login")
        if ctx.auth.throttled(client):
            log.warning("web: login locked for %s (too many failed attempts)", client)
            return login_html(ctx, request, target, "Too many failed logins from your address: the login is "
                              "locked for a minute. Wait, then try again.", status=429)
        fresh = ctx.auth.login(s, form.get("password", ""), client)
        if fresh is None:
            log.warning("web: failed login from %s", client)
            return login_html(ctx, request, target, "Wrong password.", status=401)
        log.info("web: login from %s", client)
        request.state.websession = fresh
        return RedirectResponse(target, status_code=303)

    @r.post("/logout")
    async def logout(request: Request) -> Response:
        s: WebSession = request.state.websession
        form = await _form(request)
        if not ctx.auth.csrf_ok(s, form.get(CSRF_FIELD) or request.headers.get(CSRF_HEADER)):
            return error(403, "missing or wrong CSRF token")
        ctx.auth.drop(s)
        request.state.websession = ctx.auth.create()
        return RedirectResponse("/login" if not ctx.auth.loopback else "/", status_code=303)

    return r
