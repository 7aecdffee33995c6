"""Auth glue: the guard every HTTP request passes, and the login/logout routes.

The rules themselves (who may read, who may write, CSRF tokens, sessions) live in ``security.py``;
this module applies them to requests: it finds or creates the session cookie, answers 401/403/413
before a handler runs, and sets the security headers on every response. Login and logout are form
posts (the login page works without JavaScript).
"""

from __future__ import annotations

import logging
from collections.abc import Awaitable, Callable
from html import escape
from urllib.parse import parse_qs, quote, urlsplit

from fastapi import APIRouter, FastAPI, Request, WebSocket
from fastapi.responses import HTMLResponse, RedirectResponse, Response

from . import world_api
from .context import MAX_BODY, WebContext, error
from .pages import template
from .security import COOKIE_NAME, CSRF_FIELD, CSRF_HEADER, WebSession

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


def install_guard(app: FastAPI, ctx: WebContext) -> None:
    """The session/permission/CSRF middleware and the security headers."""

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
        response.headers.setdefault("Content-Security-Policy", CSP)
        return response

    async def _check(request: Request, s: WebSession,
                     call_next: Callable[[Request], Awaitable[Response]]) -> Response:
        path = request.url.path
        if path.startswith(world_api.PREFIX):  # scripts, not browsers: own access rules
            return world_api.guard(request, ctx.auth) or await call_next(request)
        public = path.startswith("/static/") or path == "/login"
        if not public and not ctx.auth.may_read(s):
            if path.startswith("/api/") or request.method not in SAFE_METHODS:
                return error(401, "login required")
            return RedirectResponse("/login?next=" + quote(path), status_code=303)
        if request.method in SAFE_METHODS:
            return await call_next(request)
        length = request.headers.get("content-length")
        if length is not None and (not length.isdigit() or int(length) > MAX_BODY):
            return error(413, f"request body larger than {MAX_BODY} bytes")
        if not same_origin(request):
            return error(403, "cross-origin request refused")
        if path in ("/login", "/logout"):  # form posts: token checked by the handler
            return await call_next(request)
        if not ctx.auth.may_write(s):
            return error(401, "login required to change the gripper")
        if not ctx.auth.csrf_ok(s, request.headers.get(CSRF_HEADER)):
            return error(403, f"missing or wrong CSRF token (send the {CSRF_HEADER} header)")
        return await call_next(request)


async def _form(request: Request) -> dict[str, str]:
    raw = (await request.body())[:MAX_BODY].decode("utf-8", "replace")
    return {k: v[0] for k, v in parse_qs(raw, keep_blank_values=True).items()}


def safe_next(target: str) -> str:
    """Only local paths after login (no open redirect)."""
    if not target.startswith("/") or target.startswith("//") or "\\" in target:
        return "/"
    return target


def login_html(ctx: WebContext, request: Request, target: str, error_text: str, status: int = 200) -> HTMLResponse:
    s: WebSession = request.state.websession
    body = template("login.html").safe_substitute(
        csrf=escape(s.csrf), next=escape(safe_next(target)), error=escape(error_text),
        note="" if ctx.auth.login_possible else "No password is set for this interface: no login needed.",
    )
    return HTMLResponse(body, status_code=status, headers={"Cache-Control": "no-store"})


def router(ctx: WebContext) -> APIRouter:
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
        if not ctx.auth.csrf_ok(s, form.get(CSRF_FIELD)):
            return error(403, "missing or wrong CSRF token")
        if not ctx.auth.login_possible:
            return error(400, "no password is set: this interface needs no login")
        if ctx.auth.throttled(client):
            return error(429, "too many failed logins; wait a minute")
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
