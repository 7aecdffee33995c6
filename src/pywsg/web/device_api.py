"""Identity, the Motion page's further commands (50h/51h/52h, 42h, 34h–38h, jog) and Scripting.

Each is an ordinary request frame on the web's device session (``context.CommandBridge``), like
the Control Panel's motions, except jog: it is the fieldbus's JOG (``gripper.jog``, 003 §5), which
the binary protocol does not have, and the on-board script (a firmware plugin: ``gripper.load_plugin``),
which has no command either. Answers as in ``api.py``: 200, 409 refused by the device (its
status code by name), 422 invalid input naming the field. Units: mm, mm/s, N.
"""

from __future__ import annotations

from typing import Any, Literal

from fastapi import APIRouter
from fastapi.responses import JSONResponse
from pydantic import Field

from ..device import decode_fw_version
from ..protocol import Command, Status, SystemFlag
from .api import StrictBody
from .context import InputError, WebContext, command_result, motion_limits


class TagBody(StrictBody):
    tag: str = Field(max_length=64, description="device tag, at most 64 characters (000: 51h)")


class SoftLimitsBody(StrictBody):
    minus: float = Field(ge=0, allow_inf_nan=False, description="lower limit, mm")
    plus: float = Field(ge=0, allow_inf_nan=False, description="upper limit, mm")


class OverdriveBody(StrictBody):
    on: bool


class ScriptBody(StrictBody):
    name: str = Field(min_length=1, max_length=64, description="plugin name (Settings: script)")


class JogBody(StrictBody):
    direction: Literal["open", "close", "stop"]
    speed: float = Field(default=0.0, ge=0, allow_inf_nan=False, description="mm/s; 0: the minimum speed")
    force: float | None = Field(default=None, gt=0, allow_inf_nan=False, description="pressing force, N")


def firmware_text(value: int) -> str:
    """50h firmware word as text: ``4.0.2``, with ``-rcN`` for a release candidate."""
    major, minor1, minor2, rc = decode_fw_version(value)
    return f"{major}.{minor1}.{minor2}" + (f"-rc{rc}" if rc else "")


def router(ctx: WebContext) -> APIRouter:
    r = APIRouter(prefix="/api")
    bridge = ctx.bridge

    def ask(command: Command, **values: Any) -> dict[str, Any] | None:
        """A query's reply values, or None when the device has none (E_NOT_AVAILABLE, ...)."""
        status, replied = bridge.send(command, record=False, **values)
        return replied if status == Status.E_SUCCESS else None

    def run(command: Command, **values: Any) -> JSONResponse:
        status, replied = bridge.send(command, **values)
        return command_result(command, status, replied, seq=bridge.last_seq)

    @r.get("/identity")
    async def identity() -> dict[str, Any]:
        """Model, firmware, serial number, hardware revision (50h) and the device tag (52h)."""
        info = ask(Command.GET_SYSTEM_INFO) or {}
        tag = ask(Command.GET_DEVICE_TAG)
        fw = info.get("fw_version")
        return {"model": ctx.model_name(), "firmware": firmware_text(fw) if isinstance(fw, int) else None,
                "serial": info.get("sn"), "hw_revision": info.get("hwrev"),
                "tag": tag.get("tag") if tag else None,
                "location": getattr(ctx.gripper.settings, "location", None),
                "contact": getattr(ctx.gripper.settings, "contact", None)}

    @r.post("/tag")
    async def set_tag(body: TagBody) -> JSONResponse:
        status, _ = bridge.send(Command.SET_DEVICE_TAG, tag=body.tag)
        if status != Status.E_SUCCESS and isinstance(status, Status):
            raise InputError({"tag": f"refused by the device: {status.description} ({status.name})"})
        return command_result(Command.SET_DEVICE_TAG, status, seq=bridge.last_seq)

    @r.get("/statistics")
    async def statistics() -> dict[str, Any]:
        """42h: grips in total, with no part found, with the part lost."""
        return ask(Command.GET_GRIPPING_STATISTICS, flags=0) or {}

    @r.post("/statistics/reset")
    async def reset_statistics() -> JSONResponse:
        return run(Command.GET_GRIPPING_STATISTICS, flags=1)  # D0: reset after reading

    @r.get("/soft-limits")
    async def get_soft_limits() -> dict[str, Any]:
        """35h: ``{"minus", "plus"}`` in mm, or nulls when none are set."""
        got = ask(Command.GET_SOFT_LIMITS)
        return {"minus": got.get("minus"), "plus": got.get("plus")} if got else {"minus": None, "plus": None}

    @r.post("/soft-limits")
    async def set_soft_limits(body: SoftLimitsBody) -> JSONResponse:
        motion_limits(ctx, body.minus, None)
        motion_limits(ctx, body.plus, None)
        if body.minus >= body.plus:
            raise InputError({"plus": "must be greater than the lower limit"})
        return run(Command.SET_SOFT_LIMITS, minus=body.minus, plus=body.plus)

    @r.delete("/soft-limits")
    async def clear_soft_limits() -> JSONResponse:
        return run(Command.CLEAR_SOFT_LIMITS)

    @r.post("/overdrive")
    async def overdrive(body: OverdriveBody) -> JSONResponse:
        return run(Command.OVERDRIVE_MODE, flags=1 if body.on else 0)

    @r.post("/tare")
    async def tare() -> JSONResponse:
        return run(Command.TARE_FORCE_SENSOR)

    @r.post("/jog")
    async def jog(body: JogBody) -> JSONResponse:
        """Hold-to-run: ``open``/``close`` start (or keep) the jog, ``stop`` ends it."""
        motion_limits(ctx, None, body.speed or None, body.force)
        direction = {"open": 1, "close": -1, "stop": 0}[body.direction]
        force = body.force if body.force is not None else float(ctx.gripper.snapshot().force_limit)
        status = ctx.gripper.jog(direction, body.speed, force)
        body_out = {"command": "JOG", "status": Status(status).name, "code": int(status)}
        if status != Status.E_SUCCESS:
            body_out["detail"] = f"JOG refused by the device: {Status(status).description} ({Status(status).name})"
            return JSONResponse(body_out, status_code=409)
        return JSONResponse(body_out)

    # -- Scripting: the on-board script (firmware plugin) --------------------------------------------
    def script_state() -> dict[str, Any]:
        from ..device.plugins import PLUGINS  # the device's registry of plugins

        flags = int(ctx.gripper.snapshot().flags)
        return {"available": sorted(PLUGINS), "running": sorted(getattr(ctx.gripper, "plugins", {})),
                "startup": getattr(ctx.gripper.settings, "script", None),
                "script_running": bool(flags & SystemFlag.SF_SCRIPT_RUNNING),
                "script_failure": bool(flags & SystemFlag.SF_SCRIPT_FAILURE)}

    @r.get("/script")
    async def get_script() -> dict[str, Any]:
        """Which scripts exist, which runs, which starts at power-up, SF_SCRIPT_RUNNING/FAILURE."""
        return script_state()

    @r.post("/script/start")
    async def start_script(body: ScriptBody) -> dict[str, Any]:
        from ..device.plugins import PLUGINS

        if body.name not in PLUGINS:
            raise InputError({"name": f"unknown script (known: {', '.join(sorted(PLUGINS))})"})
        for running in list(ctx.gripper.plugins):  # one script at a time, as on the real device
            ctx.gripper.unload_plugin(running)
        try:
            ctx.gripper.load_plugin(body.name)
        except ValueError as exc:
            raise InputError({"name": str(exc)}) from None
        return script_state()

    @r.post("/script/stop")
    async def stop_script() -> dict[str, Any]:
        for running in list(ctx.gripper.plugins):
            ctx.gripper.unload_plugin(running)
        return script_state()

    return r
