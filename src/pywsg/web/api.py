"""The JSON API under ``/api``: state, commands to the fingers, settings, log and fieldbus.

Every motion, Stop and Ack is an ordinary request frame on the web interface's own device session
(``context.CommandBridge``), so the web obeys the rules a TCP client meets. Answers: 200 done,
202 E_CMD_PENDING (the final result follows on the WebSocket), 409 refused by the device, 422
invalid input naming each field. Bodies are strict: JSON types must match, unknown fields refused.
Units: mm, mm/s, mm/s², N, °C. Fault injection is in ``sim_api.py``.
"""

from __future__ import annotations

import csv
import dataclasses
import io
import json
import logging
import time
from typing import Any, Literal

from fastapi import APIRouter, Request
from fastapi.responses import JSONResponse, Response
from pydantic import BaseModel, ConfigDict, Field

from .. import __version__
from ..device import LogLevel
from ..protocol import Command, HomingDirection, Status
from .context import WebContext, command_result, error, motion_limits, motion_ranges
from .fieldbus_view import fieldbus_view
from .reference import catalog_json
from .security import WebSession
from .views import coerce_setting, field_of_error, jsonable, settings_schema

log = logging.getLogger(__name__)

# faults that keep a FAST STOP from being acknowledged, as the Gripper box names them
FAULT_LABELS = (("SF_POWER_FAULT", "Power Fault"), ("SF_CURR_FAULT", "Current Fault"),
                ("SF_TEMP_FAULT", "Temperature Fault"), ("SF_FINGER_FAULT", "Finger Fault"))


class StrictBody(BaseModel):
    """Request bodies: JSON types must match; out-of-range values are 422."""

    model_config = ConfigDict(strict=True, extra="forbid")


class HomeBody(StrictBody):
    direction: Literal["default", "positive", "negative"] = "default"


class MoveBody(StrictBody):
    width: float = Field(ge=0, allow_inf_nan=False, description="opening width, mm")
    speed: float = Field(gt=0, allow_inf_nan=False, description="mm/s")
    relative: bool = False
    stop_on_block: bool = False


class GripBody(StrictBody):
    width: float = Field(ge=0, allow_inf_nan=False, description="nominal part width, mm")
    speed: float = Field(gt=0, allow_inf_nan=False, description="mm/s")
    force: float | None = Field(default=None, gt=0, allow_inf_nan=False, description="force limit, N")


class ReleaseBody(StrictBody):
    width: float = Field(ge=0, allow_inf_nan=False, description="opening width, mm")
    speed: float = Field(gt=0, allow_inf_nan=False, description="mm/s")


def iso_time(t: Any) -> str:
    """Wall-clock seconds as ISO 8601 UTC with milliseconds: ``2026-11-24T18:25:03.123Z``."""
    if not isinstance(t, int | float):
        return ""
    return time.strftime("%Y-%m-%dT%H:%M:%S", time.gmtime(t)) + f".{int(t % 1 * 1000):03d}Z"


def _shown(value: Any) -> str:
    return "(none)" if value is None else json.dumps(jsonable(value))


def record_changes(ctx: WebContext, before: Any, changes: dict[str, Any]) -> None:
    """One System Log line per changed setting: which, from what, to what (issue 15 item 12)."""
    add = getattr(getattr(ctx.gripper, "log", None), "add", None)
    if not callable(add):
        return
    units = {e["name"]: e.get("unit") or "" for e in settings_schema(before)}
    for name, new in changes.items():
        old = getattr(before, name, None)
        if old == new:
            continue
        unit = f" {units[name]}" if units.get(name) else ""
        add(ctx.gripper.clock(), LogLevel.INFO,
            f"setting {name} changed from {_shown(old)} to {_shown(new)}{unit} (web interface)")


def router(ctx: WebContext) -> APIRouter:
    """The routes under /api except /api/sim."""
    r = APIRouter(prefix="/api")
    bridge = ctx.bridge

    @r.get("/csrf")
    async def csrf(request: Request) -> dict[str, Any]:
        """The session's CSRF token (same-origin pages and scripts only: no CORS)."""
        s: WebSession = request.state.websession
        return {"token": s.csrf, "authenticated": s.authenticated, "can_write": ctx.auth.may_write(s),
                "login_possible": ctx.auth.login_possible}

    @r.get("/state")
    async def state() -> dict[str, Any]:
        """Snapshot: width mm, speed mm/s, force N, temperature °C, flags, gripper state."""
        return ctx.state()

    @r.get("/info")
    async def info() -> dict[str, Any]:
        status, values = bridge.send(Command.GET_SYSTEM_INFO, record=False)
        limits = bridge.limits()
        return {"model": ctx.model_name(), "system_info": jsonable(values) if status == Status.E_SUCCESS else None,
                "limits": limits, "ranges": motion_ranges(limits), "sim": jsonable(ctx.sim_info),
                "version": __version__, "simulation": ctx.has_faults(), "fieldbus": ctx.fieldbus is not None,
                "settings_file": str(ctx.settings_path) if ctx.settings_path else None}

    # -- the fingers ------------------------------------------------------------------------------
    def run(command: Command, **values: Any) -> JSONResponse:
        """Send one command on the web's device session; its answer as HTTP (see ``command_result``)."""
        status, replied = bridge.send(command, **values)
        return command_result(command, status, replied, seq=bridge.last_seq)

    @r.post("/stop")
    async def stop() -> JSONResponse:
        return run(Command.STOP)

    @r.post("/fast-stop")
    async def fast_stop() -> JSONResponse:
        return run(Command.FAST_STOP)

    @r.post("/ack")
    async def ack() -> JSONResponse:
        resp = run(Command.ACK_FAST_STOP, key="ack")
        if resp.status_code == 409:
            # E_ACCESS_DENIED while a fault persists: say which one (the flags name it; 000 §3.2.5)
            faults = [label for name, label in FAULT_LABELS if name in ctx.state()["flag_names"]]
            if faults:
                body = json.loads(bytes(resp.body))
                body["faults"] = faults
                body["detail"] = (f"Ack refused: {' and '.join(faults)} still active; the FAST STOP cannot be "
                                  "acknowledged until the fault is gone (Simulation page: switch the fault off)")
                return JSONResponse(body, status_code=409)
        return resp

    @r.post("/home")
    async def home(body: HomeBody | None = None) -> JSONResponse:
        direction = HomingDirection[(body.direction if body else "default").upper()]
        return run(Command.HOMING, direction=int(direction))

    @r.post("/move")
    async def move(body: MoveBody) -> JSONResponse:
        motion_limits(ctx, body.width, body.speed, relative=body.relative)
        flags = (1 if body.relative else 0) | (2 if body.stop_on_block else 0)
        return run(Command.PREPOSITION, flags=flags, width=body.width, speed=body.speed)

    @r.post("/grip")
    async def grip(body: GripBody) -> JSONResponse:
        motion_limits(ctx, body.width, body.speed, body.force)
        if body.force is not None:
            status, _ = bridge.send(Command.SET_FORCE_LIMIT, force=body.force)
            if status != Status.E_SUCCESS:
                return command_result(Command.SET_FORCE_LIMIT, status, seq=bridge.last_seq)
        return run(Command.GRIP_PART, width=body.width, speed=body.speed)

    @r.post("/release")
    async def release(body: ReleaseBody) -> JSONResponse:
        motion_limits(ctx, body.width, body.speed)
        return run(Command.RELEASE_PART, width=body.width, speed=body.speed)

    @r.get("/results")
    async def results(after: int = 0) -> list[dict[str, Any]]:
        """Results of commands sent from the web interface (immediate and final)."""
        return [e for e in bridge.results if e["seq"] > after]

    # -- settings ---------------------------------------------------------------------------------
    def settings_body() -> dict[str, Any]:
        current = ctx.gripper.settings
        return {"values": jsonable(current), "fields": settings_schema(current),
                "settings_file": str(ctx.settings_path) if ctx.settings_path else None,
                "interfaces": jsonable(ctx.sim_info)}

    @r.get("/settings")
    async def get_settings() -> dict[str, Any]:
        return settings_body()

    @r.post("/settings")
    async def post_settings(request: Request) -> Response:
        """Change some settings: a JSON object {name: value}. 422 names each refused field."""
        data = await request.body()
        try:
            raw = json.loads(data)
        except (ValueError, UnicodeDecodeError):
            return error(422, "invalid input: body is not JSON", {"_": "body is not JSON"})
        except RecursionError:  # e.g. 5,000 nested [[[...]]]: the parser gives up, so do we
            return error(422, "invalid input: JSON nested too deeply", {"_": "JSON nested too deeply"})
        if not isinstance(raw, dict) or not raw:
            return error(422, "invalid input: expected a JSON object of settings",
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
            return error(422, "invalid input: " + "; ".join(f"{k}: {v}" for k, v in errors.items()), errors)
        try:
            new = dataclasses.replace(current, **changes)
            ctx.gripper.apply_settings(new)
        except (ValueError, TypeError, OverflowError) as exc:
            field, reason = field_of_error(str(exc), list(schema))
            return error(422, f"invalid input: {exc}", {field: reason})
        saved = None
        if ctx.settings_path is not None:
            try:
                ctx.gripper.settings.save(ctx.settings_path)
                saved = str(ctx.settings_path)
            except OSError as exc:
                return error(500, f"applied, but not saved to {ctx.settings_path}: {exc}")
        log.info("web: settings changed: %s", ", ".join(changes))
        record_changes(ctx, current, changes)
        body = settings_body()
        body["changed"] = sorted(changes)
        body["saved"] = saved
        return JSONResponse(body)

    # -- diagnosis --------------------------------------------------------------------------------
    @r.get("/log")
    async def get_log(after: int = 0, limit: int = 500) -> Response:
        if after < 0 or not 1 <= limit <= 2000:
            return error(422, "invalid input: after >= 0, 1 <= limit <= 2000",
                         {"after" if after < 0 else "limit": "out of range"})
        return JSONResponse({"entries": ctx.log_feed.after(after, limit), "last": ctx.log_feed.seq})

    @r.get("/log/export")
    async def export_log(format: Literal["csv", "json"] = "csv") -> Response:
        """The whole log as a file: CSV (seq, ISO time UTC, level, message) or JSON lines."""
        entries = ctx.log_feed.after(0, ctx.log_feed.entries.maxlen or 2000)
        stamp = time.strftime("%Y%m%dT%H%M%SZ", time.gmtime())
        if format == "json":
            text = "".join(json.dumps({**e, "iso_time": iso_time(e.get("wall_time"))}) + "\n" for e in entries)
            media = "application/x-ndjson"
        else:
            out = io.StringIO()
            w = csv.writer(out)
            w.writerow(["seq", "time_utc", "level", "message"])
            for e in entries:
                w.writerow([e["seq"], iso_time(e.get("wall_time")), e.get("level", ""), e.get("message", "")])
            text, media = out.getvalue(), "text/csv; charset=utf-8"
        name = f"wsg-system-log-{stamp}.{'jsonl' if format == 'json' else 'csv'}"
        return Response(text, media_type=media, headers={"Content-Disposition": f'attachment; filename="{name}"'})

    @r.get("/fieldbus")
    async def get_fieldbus() -> dict[str, Any]:
        return fieldbus_view(ctx.fieldbus)

    @r.get("/commands")
    async def commands() -> list[dict[str, Any]]:
        return catalog_json()

    return r
