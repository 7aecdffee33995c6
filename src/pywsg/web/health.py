"""``GET /healthz``: is this web interface (and so its ``wsg sim``) up? For container health checks
and Kubernetes probes (docs/container.md).

It answers without a login, also off loopback, and tells nothing about the gripper (``{"status":
"ok"}``): a probe has no password, and an anonymous caller must learn nothing it could not learn from
the open port. It opens no device session, so it never takes the command interface from a client nor
raises FAST STOP (a TCP probe would: a connection closed without 07h is a FAST STOP, 000 §3.1.2; a UDP
probe would take the auto-update packets from the last UDP client). A FAST STOP is a state the
gripper is in, not a fault of the container, so it does not make the probe fail.
"""

from __future__ import annotations

from fastapi import APIRouter
from fastapi.responses import JSONResponse

from .context import WebContext

PATH = "/healthz"


def router(ctx: WebContext) -> APIRouter:
    """The health route (``ctx`` unused: the answer depends on no state)."""
    r = APIRouter(include_in_schema=False)

    @r.get(PATH)
    async def healthz() -> JSONResponse:
        return JSONResponse({"status": "ok"}, headers={"Cache-Control": "no-store"})

    return r
