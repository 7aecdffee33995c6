"""Scripting: the on-board script of the real panel (003 menu "Scripting"), here a firmware plugin.

A real WSG runs one Lua script at a time; the virtual gripper runs :mod:`pywsg.device.plugins`
objects in its place. This page shows which one runs, starts one (stopping the one before) or
stops it, and shows the two system flags of 000 Appendix B: SF_SCRIPT_RUNNING (D19, set while a
script runs) and SF_SCRIPT_FAILURE (D20, the script ended with an error).

Start and stop go through the gripper's public ``load_plugin`` / ``unload_plugin``. A plugin whose
``start`` raises is a script that failed: it is stopped again and SF_SCRIPT_FAILURE is raised
(``script_failure``; the device clears it when the next script starts). Which script starts at
power-up is the ``script`` setting (Settings → Motion Configuration), not changed here.
"""

from __future__ import annotations

import logging
from typing import Any

from fastapi import APIRouter, Request
from fastapi.responses import HTMLResponse, JSONResponse, Response
from pydantic import BaseModel, ConfigDict

from ..device.plugins import PLUGINS
from ..protocol import SystemFlag
from .context import WebContext, error
from .pages import render_page

log = logging.getLogger(__name__)


class StartBody(BaseModel):
    model_config = ConfigDict(strict=True, extra="forbid")
    plugin: str


def _doc_line(cls: type) -> str:
    doc = (cls.__doc__ or "").strip()
    return doc.splitlines()[0] if doc else ""


def scripting_view(gripper: Any) -> dict[str, Any]:
    """Running plugins, the available ones (name, command IDs, description) and both script flags."""
    flags = int(gripper.system_flags())
    settings = getattr(gripper, "settings", None)
    return {
        "running": list(gripper.plugins),
        "available": [
            {"name": name, "commands": [f"{c:02X}h" for c in cls.commands], "description": _doc_line(cls)}
            for name, cls in PLUGINS.items()
        ],
        "script_running": bool(flags & SystemFlag.SF_SCRIPT_RUNNING),
        "script_failure": bool(flags & SystemFlag.SF_SCRIPT_FAILURE),
        "startup": getattr(settings, "script", None),
    }


def router(ctx: WebContext) -> APIRouter:
    """``GET /scripting`` (page), ``GET /api/scripting``, ``POST /api/scripting/start`` and ``/stop``."""
    r = APIRouter()
    g = ctx.gripper

    @r.get("/scripting", response_class=HTMLResponse, include_in_schema=False)
    async def page(request: Request) -> HTMLResponse:
        return render_page(ctx, request, "/scripting", "Scripting", "scripting.html", "scripting")

    @r.get("/api/scripting")
    async def get_scripting() -> dict[str, Any]:
        return scripting_view(g)

    @r.post("/api/scripting/start")
    async def start(body: StartBody) -> Response:
        """Start ``plugin`` (one of ``available``); a running script is stopped first. 409: it failed."""
        if body.plugin not in PLUGINS:
            return error(422, f"invalid input: plugin: unknown plugin {body.plugin!r}",
                         {"plugin": f"one of {', '.join(PLUGINS)}"})
        for name in list(g.plugins):
            g.unload_plugin(name)
        try:
            g.load_plugin(body.plugin)
        except Exception as exc:  # a script that fails to start is SF_SCRIPT_FAILURE, not a 500
            log.warning("web: script %s failed to start: %s", body.plugin, exc)
            g.unload_plugin(body.plugin)
            g.script_failure = True
            g.changed()
            view = scripting_view(g)
            view["detail"] = f"script {body.plugin} failed to start: {exc}"
            return JSONResponse(view, status_code=409)
        return JSONResponse(scripting_view(g))

    @r.post("/api/scripting/stop")
    async def stop() -> dict[str, Any]:
        """Stop the running script (nothing running: nothing to do)."""
        for name in list(g.plugins):
            g.unload_plugin(name)
        return scripting_view(g)

    return r
