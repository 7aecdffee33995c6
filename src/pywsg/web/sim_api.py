"""The Simulation page's API under ``/api/sim``: fault injection on the virtual gripper.

Place or remove a part, block the fingers, heat up or cool down, switch power / motor current /
finger faults. These call ``gripper.faults`` directly (a real gripper has none: 422 says so);
a value the device refuses is a 422 naming the field. Units: mm, N/mm, °C.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from typing import Any, Literal

from fastapi import APIRouter
from pydantic import Field

from ..testing.world import world_state
from .api import StrictBody
from .context import InputError, WebContext, motion_limits
from .views import field_of_error

log = logging.getLogger(__name__)


class PartBody(StrictBody):
    width: float = Field(gt=0, allow_inf_nan=False, description="part width, mm")
    stiffness: float | None = Field(default=None, gt=0, allow_inf_nan=False, description="N/mm")
    inside: bool = Field(default=False, description="gripped from inside (a ring); default from outside")


class BlockBody(StrictBody):
    width: float = Field(ge=0, allow_inf_nan=False, description="width where the fingers block, mm")


class HeatBody(StrictBody):
    delta_c: float = Field(ge=-200, le=200, allow_inf_nan=False, description="temperature change, °C")


class FaultBody(StrictBody):
    kind: Literal["power", "current", "finger"]
    on: bool
    finger: Literal[1, 2] = 1


def router(ctx: WebContext) -> APIRouter:
    """POST/DELETE /api/sim/part, /api/sim/block; POST /api/sim/heat, /api/sim/fault."""
    r = APIRouter(prefix="/api/sim")

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

    @r.get("/world")
    async def world() -> dict[str, Any]:
        """The part, block, faults and temperature now (what the Simulation page shows)."""
        return world_state(ctx.gripper)

    def done(action: str) -> dict[str, Any]:
        log.info("web: simulation: %s", action)
        return {"ok": True, "action": action, "state": ctx.state()}

    @r.post("/part")
    async def place_part(body: PartBody) -> dict[str, Any]:
        motion_limits(ctx, body.width, None)
        if body.stiffness is None:
            inject(faults().place_part, body.width, inside=body.inside)
        else:
            inject(faults().place_part, body.width, stiffness=body.stiffness, inside=body.inside)
        return done(f"part of {body.width:g} mm placed")

    @r.delete("/part")
    async def remove_part() -> dict[str, Any]:
        faults().remove_part()
        return done("part removed")

    @r.post("/block")
    async def block(body: BlockBody) -> dict[str, Any]:
        motion_limits(ctx, body.width, None)
        inject(faults().block_at, body.width)
        return done(f"fingers blocked at {body.width:g} mm")

    @r.delete("/block")
    async def unblock() -> dict[str, Any]:
        faults().unblock()
        return done("fingers unblocked")

    @r.post("/heat")
    async def heat(body: HeatBody) -> dict[str, Any]:
        inject(faults().heat, body.delta_c)
        return done(f"temperature changed by {body.delta_c:+g} °C")

    @r.post("/fault")
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

    return r
