"""The Commander's predefined commands (000 §2 "Main Window"): one row per command, in the manual's units.

Each row names the command by its catalog ID and title, lists its parameters (millimetres, mm/s,
mm/s², newtons, as the manual's command reference gives them) and says which driver method sends
it. The page builds its forms from :func:`catalog_json`; the server runs a row with :func:`run`.
Motion commands (20h, 21h, 25h, 26h) return at E_CMD_PENDING: their final reply follows on the
live stream, so Stop and FAST STOP stay usable while they run.
"""

from __future__ import annotations

from collections.abc import Awaitable, Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

from ...protocol import CATALOG, Command

__all__ = ["PREDEFINED", "Param", "Predefined", "catalog_json", "coerce"]


@dataclass(frozen=True)
class Param:
    """A parameter: ``kind`` number (float in ``unit``), choice (one of ``choices``), bool or text."""

    name: str
    label: str
    unit: str = ""
    kind: str = "number"
    default: Any = None
    choices: tuple[str, ...] = ()
    optional: bool = False


Call = Callable[[Any, Mapping[str, Any]], Awaitable[Any]]


@dataclass(frozen=True)
class Predefined:
    """One predefined command: ``call(gripper, values)`` sends it through the driver."""

    key: str
    command: Command
    call: Call
    params: tuple[Param, ...] = ()
    motion: bool = False
    group: str = "State"
    label: str = field(default="")

    @property
    def title(self) -> str:
        return self.label or CATALOG[self.command].title


WIDTH = Param("width", "Width", "mm", default=50.0)
SPEED = Param("speed", "Speed", "mm/s", default=50.0)


def _motion(method: str, *names: str) -> Call:
    async def call(g: Any, v: Mapping[str, Any]) -> Any:
        kwargs = {n: v[n] for n in names if v.get(n) is not None}
        return await getattr(g, method)(**kwargs, wait=False)
    return call


def _plain(method: str, *names: str) -> Call:
    async def call(g: Any, v: Mapping[str, Any]) -> Any:
        return await getattr(g, method)(*(v[n] for n in names))
    return call


PREDEFINED: tuple[Predefined, ...] = (
    Predefined("home", Command.HOMING, _motion("home", "direction"), (
        Param("direction", "Direction", kind="choice", default="default", choices=("default", "positive", "negative")),
    ), motion=True, group="Motion"),
    Predefined("move", Command.PREPOSITION, _motion("move", "width", "speed", "relative", "stop_on_block"), (
        WIDTH, SPEED, Param("relative", "Relative", kind="bool", default=False),
        Param("stop_on_block", "Stop on block", kind="bool", default=False),
    ), motion=True, group="Motion"),
    Predefined("grip", Command.GRIP_PART, _motion("grip", "width", "speed", "force"), (
        Param("width", "Part width", "mm", default=20.0), SPEED,
        Param("force", "Force limit (32h first)", "N", optional=True),
    ), motion=True, group="Motion"),
    Predefined("release", Command.RELEASE_PART, _motion("release", "width", "speed"), (
        Param("width", "Open to width", "mm", default=60.0), SPEED,
    ), motion=True, group="Motion"),
    Predefined("stop", Command.STOP, _plain("stop"), group="Motion"),
    Predefined("fast_stop", Command.FAST_STOP, _plain("fast_stop"), group="Motion"),
    Predefined("ack", Command.ACK_FAST_STOP, _plain("acknowledge"), group="Motion"),
    Predefined("set_acceleration", Command.SET_ACCELERATION, _plain("set_acceleration", "acceleration"), (
        Param("acceleration", "Acceleration", "mm/s²", default=200.0),), group="Motion configuration"),
    Predefined("get_acceleration", Command.GET_ACCELERATION, _plain("acceleration"), group="Motion configuration"),
    Predefined("set_force_limit", Command.SET_FORCE_LIMIT, _plain("set_force_limit", "force"), (
        Param("force", "Force limit", "N", default=40.0),), group="Motion configuration"),
    Predefined("get_force_limit", Command.GET_FORCE_LIMIT, _plain("force_limit"), group="Motion configuration"),
    Predefined("set_soft_limits", Command.SET_SOFT_LIMITS, _plain("set_soft_limits", "minus", "plus"), (
        Param("minus", "Minus limit", "mm", default=0.0), Param("plus", "Plus limit", "mm", default=110.0),
    ), group="Motion configuration"),
    Predefined("get_soft_limits", Command.GET_SOFT_LIMITS, _plain("soft_limits"), group="Motion configuration"),
    Predefined("clear_soft_limits", Command.CLEAR_SOFT_LIMITS, _plain("clear_soft_limits"),
               group="Motion configuration"),
    Predefined("overdrive", Command.OVERDRIVE_MODE, _plain("overdrive", "enable"), (
        Param("enable", "Enable", kind="bool", default=True),), group="Motion configuration"),
    Predefined("tare", Command.TARE_FORCE_SENSOR, _plain("tare"), group="Motion configuration"),
    Predefined("system_state", Command.GET_SYSTEM_STATE, _plain("system_state")),
    Predefined("gripper_state", Command.GET_GRIPPER_STATE, _plain("gripper_state")),
    Predefined("statistics", Command.GET_GRIPPING_STATISTICS, _plain("statistics", "reset"), (
        Param("reset", "Reset after reading", kind="bool", default=False),)),
    Predefined("width", Command.GET_OPENING_WIDTH, _plain("width")),
    Predefined("speed", Command.GET_SPEED, _plain("speed")),
    Predefined("force", Command.GET_FORCE, _plain("force")),
    Predefined("temperature", Command.GET_TEMPERATURE, _plain("temperature")),
    Predefined("info", Command.GET_SYSTEM_INFO, _plain("info"), group="System"),
    Predefined("set_tag", Command.SET_DEVICE_TAG, _plain("set_tag", "tag"), (
        Param("tag", "Tag", kind="text", default=""),), group="System"),
    Predefined("get_tag", Command.GET_DEVICE_TAG, _plain("tag"), group="System"),
    Predefined("limits", Command.GET_SYSTEM_LIMITS, _plain("limits"), group="System"),
    Predefined("loop", Command.LOOP, _plain("loop", "data"), (
        Param("data", "Data (text)", kind="text", default="pywsg"),), group="System"),
)

BY_KEY: dict[str, Predefined] = {p.key: p for p in PREDEFINED}


def coerce(p: Predefined, given: Mapping[str, Any]) -> tuple[dict[str, Any], dict[str, str]]:
    """The parameters of ``p`` from a request body: (values, errors by field)."""
    values: dict[str, Any] = {}
    errors: dict[str, str] = {}
    for param in p.params:
        raw = given.get(param.name, param.default)
        if raw is None or raw == "":
            if param.optional:
                values[param.name] = None
            else:
                errors[param.name] = "required"
            continue
        if param.kind == "number":
            try:
                number = float(raw)
            except (TypeError, ValueError):
                errors[param.name] = f"a number in {param.unit}"
                continue
            if number != number or number in (float("inf"), float("-inf")):
                errors[param.name] = f"a finite number in {param.unit}"
                continue
            values[param.name] = number
        elif param.kind == "bool":
            values[param.name] = raw in (True, "true", "on", "1", 1)
        elif param.kind == "choice":
            if raw not in param.choices:
                errors[param.name] = "one of " + ", ".join(param.choices)
                continue
            values[param.name] = raw
        else:
            values[param.name] = str(raw)
    if p.key == "loop":
        try:
            values["data"] = str(values.get("data", "")).encode("latin-1")
        except UnicodeEncodeError:
            errors["data"] = "text of one-byte characters (Latin-1)"
    return values, errors


def catalog_json() -> list[dict[str, Any]]:
    """The rows for the page: key, ID, title, group, motion and the parameters."""
    return [{
        "key": p.key, "id": int(p.command), "hex": f"{int(p.command):02X}h", "title": p.title, "group": p.group,
        "motion": p.motion,
        "params": [{"name": q.name, "label": q.label, "unit": q.unit, "kind": q.kind, "default": q.default,
                    "choices": list(q.choices), "optional": q.optional} for q in p.params],
    } for p in PREDEFINED]
