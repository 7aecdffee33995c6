"""The world control API: steer a running ``wsg sim`` from scripts in any language (docs/testing.md).

::

    GET    /api/world              state: gripper state, width, force, temperature, part, obstacle, faults
    POST   /api/world/part         {"width": 22.0, "stiffness": 500}   put a part between the fingers
                                   {"width": 40.0, "inside": true}     a ring, gripped from inside
    DELETE /api/world/part                                              take it away
    POST   /api/world/block        {"width": 30.0}                      a rigid obstacle at 30 mm
    DELETE /api/world/block
    POST   /api/world/fault        {"kind": "power"|"current"|"finger", "on": true, "finger": 1}
    POST   /api/world/heat         {"delta_c": 40.0}
    POST   /api/world/slip         {"duration": 1.0}                    the held part slides out
    POST   /api/world/disconnect                                        the gripper closes its connections
    POST   /api/world/net          {"kind": "latency", "ms": 200, "jitter": 50, "on": true}
    DELETE /api/world/net                                               every network fault off

Replies are JSON: ``{"ok": true, "action": "part of 22 mm placed (outside, between the fingers)",
"state": {...}}``; a refused value gives 422 ``{"detail": ..., "errors": {"width": "must be within 0..110 mm ..."}}``.

Access. This API is for programs, not browsers, so it needs neither cookies nor CSRF tokens:

- a request that carries an ``Origin`` or ``Sec-Fetch-Site`` header (what browsers add) is refused
  (403): a web page must not be able to reach it (the browser pages use ``/api/sim/*`` with CSRF);
- on a loopback-bound server without a password it is open, but the ``Host`` header must name a
  loopback address (``127.0.0.1``, ``localhost``, ``[::1]``), so a DNS-rebinding page cannot use it;
- elsewhere (or with a password) it needs the web password as ``Authorization: Bearer PASSWORD``
  (or HTTP Basic with any user name), with the login's failure throttling.
"""

from __future__ import annotations

import base64
import binascii
import hmac
import json
from collections.abc import Awaitable, Callable
from typing import Any

from fastapi import APIRouter, Request
from fastapi.responses import JSONResponse

from ..testing.world import HTTP_ROUTES, WorldError, apply, world_state
from .context import WebContext, error
from .security import Auth, is_loopback_host

PREFIX = "/api/world"
MAX_BODY = 4096


def _error(status: int, detail: str, errors: dict[str, str] | None = None) -> JSONResponse:
    response = error(status, detail, errors)
    if status == 401:
        response.headers["WWW-Authenticate"] = 'Bearer realm="wsg"'
    return response


def _host_name(host_header: str) -> str:
    """``127.0.0.1:8080`` -> ``127.0.0.1``; ``[::1]:8080`` -> ``::1``."""
    if host_header.startswith("["):
        return host_header[1:].split("]", 1)[0]
    return host_header.rsplit(":", 1)[0] if host_header.count(":") == 1 else host_header


def _password(request: Request) -> str | None:
    value = request.headers.get("authorization", "")
    scheme, _, cred = value.partition(" ")
    if scheme.lower() == "bearer":
        return cred.strip()
    if scheme.lower() == "basic":
        try:
            return base64.b64decode(cred.strip(), validate=True).decode("utf-8").partition(":")[2]
        except (binascii.Error, UnicodeDecodeError):
            return None
    return None


def guard(request: Request, auth: Auth) -> JSONResponse | None:
    """None when ``request`` may use the world API, else the error reply (see the module docstring)."""
    if request.headers.get("origin") is not None or request.headers.get("sec-fetch-site", "none") != "none":
        return _error(403, "the world control API is for programs, not browser pages "
                           "(the Simulation page uses /api/sim with a CSRF token)")
    length = request.headers.get("content-length")
    if length is not None and (not length.isdigit() or int(length) > MAX_BODY):
        return _error(413, f"request body larger than {MAX_BODY} bytes")
    if auth.loopback and auth.password is None:
        if not is_loopback_host(_host_name(request.headers.get("host", ""))):
            return _error(403, "Host header must name a loopback address (127.0.0.1, localhost, [::1])")
        return None
    client = request.client.host if request.client else "?"
    if auth.throttled(client):
        return _error(429, "too many failed logins; wait a minute")
    given = _password(request)
    if given is None:
        return _error(401, "password required: send 'Authorization: Bearer PASSWORD'")
    if auth.password is None or not hmac.compare_digest(auth.password.encode(), given.encode()):
        probe = auth.create()  # record the failure the way a wrong login form would
        auth.login(probe, given, client)
        auth.drop(probe)
        return _error(401, "wrong password")
    return None


async def _do(gripper: Any, request: Request, action: str, with_body: bool) -> JSONResponse:
    params: dict[str, Any] = {}
    if with_body:
        raw = await request.body()
        try:
            params = json.loads(raw or b"{}")
        except (ValueError, UnicodeDecodeError, RecursionError):  # RecursionError: nesting 1,000+ deep
            return _error(422, "invalid input: body is not JSON", {"_": "not JSON"})
        if not isinstance(params, dict):
            return _error(422, "invalid input: body must be a JSON object", {"_": "not an object"})
    try:
        text = apply(gripper, action, params)
    except WorldError as exc:
        return _error(422, f"invalid input: {exc}", {exc.field: exc.reason})
    return JSONResponse({"ok": True, "action": text, "state": world_state(gripper)})


def router(ctx: WebContext) -> APIRouter:
    """GET /api/world and the world actions (access: :func:`guard`, applied by the auth middleware)."""
    r = APIRouter(prefix=PREFIX)

    @r.get("")
    async def state() -> JSONResponse:
        return JSONResponse(world_state(ctx.gripper))

    def make(action: str, with_body: bool) -> Callable[[Request], Awaitable[JSONResponse]]:
        async def endpoint(request: Request) -> JSONResponse:
            return await _do(ctx.gripper, request, action, with_body)

        endpoint.__name__ = f"world_{action}"
        return endpoint

    for method, path, action, with_body in HTTP_ROUTES:
        r.add_api_route(path, make(action, with_body), methods=[method])
    return r
