"""The world around one virtual gripper: what lies between its fingers, faults, heat.

One set of world actions that every front end shares — the pytest fixture's ``wsg_sim.world``,
the HTTP control API (``/api/world``, :mod:`pywsg.web.world_api`), ``wsg world``, ``wsg sim
--part/--block`` and scenario files. Each action is a thin, validated call into the gripper's
fault-injection facade (``gripper.faults``); it must run on the thread that owns the gripper.

Units: widths in mm, stiffness in N/mm, temperature change in °C, time in s.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from . import world_faults

__all__ = ["ACTIONS", "FAULT_KINDS", "HTTP_ROUTES", "PARAMETERS", "WorldActions", "WorldError", "apply",
           "check_parameters", "world_state"]

FAULT_KINDS = ("power", "current", "finger", "ack", "watchdog", "unplugged")
"""Faults that can be switched on and off (command manual 000 Appendix B flags SF_POWER_FAULT,
SF_CURR_FAULT, SF_FINGER_FAULT; acknowledge refused, the silent-client watchdog and an unplugged
finger: :mod:`pywsg.testing.world_faults`)."""

ACTIONS = ("part", "remove_part", "block", "unblock", "fault", "heat", "slip", "disconnect", "net")
"""Names of the world actions (also the ``do`` key of a scenario event)."""

HTTP_ROUTES = (
    ("POST", "/part", "part", True),
    ("DELETE", "/part", "remove_part", False),
    ("POST", "/block", "block", True),
    ("DELETE", "/block", "unblock", False),
    ("POST", "/fault", "fault", True),
    ("POST", "/heat", "heat", True),
    ("POST", "/slip", "slip", True),
    ("POST", "/disconnect", "disconnect", False),
    ("POST", "/net", "net", True),
    ("DELETE", "/net", "net_clear", False),
)
"""The world actions over HTTP (``/api/world`` + path, :mod:`pywsg.web.world_api`): method, path, action,
whether the action's parameters travel as a JSON body."""

PARAMETERS: dict[str, frozenset[str]] = {
    "part": frozenset({"width", "stiffness", "inside"}),
    "remove_part": frozenset(),
    "block": frozenset({"width"}),
    "unblock": frozenset(),
    "fault": frozenset({"kind", "on", "finger", "timeout"}),
    "heat": frozenset({"delta_c"}),
    "slip": frozenset({"duration"}),
    "disconnect": frozenset(),
    "net": frozenset(),  # its kind's own parameters: pywsg.server.netfault checks those
}
"""The parameters each world action takes: any other key is refused (a typo such as ``widht`` would
otherwise be ignored, and the part placed with no width or the default one)."""


def check_parameters(action: str, params: Mapping[str, Any]) -> None:
    """Raise :class:`WorldError` naming the first parameter ``action`` does not take."""
    allowed = PARAMETERS.get(action)
    if allowed is None or action == "net":
        return
    unknown = sorted(set(params) - allowed)
    if unknown:
        takes = ", ".join(sorted(allowed)) or "no parameters"
        raise WorldError(unknown[0], f"not a parameter of {action} (it takes {takes})")


class WorldError(ValueError):
    """A world action was refused: ``field`` names the parameter, the message says why."""

    def __init__(self, field: str, reason: str) -> None:
        super().__init__(f"{field}: {reason}")
        self.field = field
        self.reason = reason


def _number(params: Mapping[str, Any], name: str, default: float | None = None) -> float:
    """A JSON/TOML number: strings are refused (``"2_2"`` is not 22), as by the strict web API."""
    value = params.get(name, default)
    if value is None:
        raise WorldError(name, "missing")
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise WorldError(name, f"must be a number, not {_show(value)}")
    try:
        out = float(value)
    except OverflowError:  # a 400-digit integer
        raise WorldError(name, "must be a finite number") from None
    if not math.isfinite(out):
        raise WorldError(name, "must be a finite number")
    return out


def _show(value: Any) -> str:
    """``repr`` cut short: a refused value may be huge."""
    text = repr(value) if not isinstance(value, int) or value.bit_length() < 64 else "a huge integer"
    return text if len(text) <= 40 else text[:37] + "..."


def _width(gripper: Any, params: Mapping[str, Any]) -> float:
    width = _number(params, "width")
    stroke = float(getattr(getattr(gripper, "profile", None), "stroke", math.inf))
    if not 0 <= width <= stroke:
        raise WorldError("width", f"must be within 0..{stroke:g} mm (the stroke), not {width:g}")
    return width


def _inside(params: Mapping[str, Any]) -> bool:
    """``inside``: true grips the part from inside (a ring around the fingers), false (the default)
    from outside (a part between the fingers), whatever the fingers' width when it is placed."""
    value = params.get("inside", False)
    if value is None:
        return False
    if isinstance(value, bool):
        return value
    raise WorldError("inside", f"must be true (gripped from inside) or false (from outside), not {_show(value)}")


def apply(gripper: Any, action: str, params: Mapping[str, Any] | None = None) -> str:
    """Carry out one world ``action`` on ``gripper``; returns what was done, in words.

    ``action``/``params``: ``part`` (width, stiffness=None, inside=False: gripped from outside unless
    True), ``remove_part``, ``block`` (width),
    ``unblock``, ``fault`` (kind: power|current|finger|ack|watchdog|unplugged, on=True, finger=1|2
    for finger and unplugged, timeout=s for watchdog), ``heat`` (delta_c), ``slip`` (duration=s: the
    part slides out), ``disconnect`` (the gripper closes its connections), ``net`` (kind: a network fault of
    :mod:`pywsg.server.netfault` or ``clear``, on=True, its parameters). Raises :class:`WorldError`.
    """
    p: Mapping[str, Any] = params or {}
    faults = getattr(gripper, "faults", None)
    if faults is None:
        raise WorldError("_", "this gripper has no world to change (not a virtual gripper)")
    check_parameters(action, p)
    try:
        if action == "part":
            width = _width(gripper, p)
            inside = _inside(p)
            side = "inside, a ring gripped from inside" if inside else "outside, between the fingers"
            if p.get("stiffness") is None:
                faults.place_part(width, inside=inside)
                return f"part of {width:g} mm placed ({side})"
            stiffness = _number(p, "stiffness")
            if stiffness <= 0:
                raise WorldError("stiffness", "must be positive (N/mm)")
            faults.place_part(width, stiffness=stiffness, inside=inside)
            return f"part of {width:g} mm ({stiffness:g} N/mm) placed ({side})"
        if action == "remove_part":
            faults.remove_part()
            return "part removed"
        if action == "block":
            width = _width(gripper, p)
            faults.block_at(width)
            return f"fingers blocked at {width:g} mm"
        if action == "unblock":
            faults.unblock()
            return "fingers unblocked"
        if action == "heat":
            delta = _number(p, "delta_c")
            faults.heat(delta)
            return f"temperature changed by {delta:+g} °C"
        if action == "fault":
            return _fault(faults, p, gripper)
        if action == "slip":
            return world_faults.slip(gripper, _seconds(p, "duration", 1.0))
        if action == "disconnect":
            return world_faults.interrupt(gripper)
        if action == "net":
            return _net(gripper, p)
        if action == "net_clear":
            return _net(gripper, {"kind": "clear"})
    except WorldError:
        raise
    except ValueError as exc:  # the device names the field: "width: must be ..."
        field, _, reason = str(exc).partition(": ")
        raise WorldError(field if reason else "_", reason or str(exc)) from None
    raise WorldError("action", f"unknown world action {action!r} (one of {', '.join(ACTIONS)})")


def _seconds(p: Mapping[str, Any], name: str, default: float) -> float:
    value = _number(p, name, default)
    if value < 0:
        raise WorldError(name, f"must be a non-negative number of seconds, not {value:g}")
    return value


def _finger(p: Mapping[str, Any]) -> int:
    finger = int(_number(p, "finger", 1))
    if finger not in (1, 2):
        raise WorldError("finger", f"must be 1 or 2, not {finger}")
    return finger


def _net(gripper: Any, p: Mapping[str, Any]) -> str:
    from ..server.netfault import NetFaultError, net_faults

    kind = str(p.get("kind", ""))
    nf = net_faults(gripper)
    if kind == "clear":
        return nf.clear()
    try:
        return nf.set(kind, {k: v for k, v in p.items() if k != "kind"})
    except NetFaultError as exc:
        raise WorldError(exc.field, exc.reason) from None


def _fault(faults: Any, p: Mapping[str, Any], gripper: Any = None) -> str:
    from ..server.netfault import on_param

    kind = str(p.get("kind", ""))
    on = on_param(p, WorldError)
    state = "on" if on else "off"
    if kind == "ack":
        return world_faults.acknowledge_refused(gripper, on)
    if kind == "watchdog":
        return world_faults.watchdog(gripper, _seconds(p, "timeout", 1.0) if on else None)
    if kind == "unplugged":
        return world_faults.unplug_finger(gripper, _finger(p) - 1, on)
    if kind == "power":
        faults.power_fault(on)
        return f"power fault {state}"
    if kind == "current":
        faults.current_fault(on)
        return f"current fault {state}"
    if kind == "finger":
        finger = int(_number(p, "finger", 1))
        if finger not in (1, 2):
            raise WorldError("finger", f"must be 1 or 2, not {finger}")
        faults.finger_fault(finger - 1, on)  # the device counts fingers from 0, the manual from 1
        return f"finger {finger} fault {state}"
    raise WorldError("kind", f"must be one of {', '.join(FAULT_KINDS)}, not {kind!r}")


def world_state(gripper: Any) -> dict[str, Any]:
    """The world and the gripper's state as plain JSON values (``wsg world state``, ``GET /api/world``).

    ``time`` s on the gripper's clock; ``width`` mm; ``force`` N; ``temperature`` °C; ``part`` and
    ``blocked_at`` mm or null; ``faults`` the switchable faults that are on.
    """
    snap = gripper.snapshot()
    on = [kind for kind, attr in (("power", "power_fault"), ("current", "current_fault"))
          if getattr(gripper, attr, False)]
    on += [f"finger {i + 1}" for i, f in enumerate(getattr(gripper, "fingers", ()))
           if getattr(f, "fault", False)]
    on += world_faults.active(gripper)
    return {
        "time": round(float(snap.time), 6),
        "model": snap.model,
        "gripper_state": snap.gripper_state.name,
        "width": round(float(snap.width), 3),
        "force": round(float(snap.force), 3),
        "temperature": round(float(snap.temperature), 2),
        "fast_stop": bool(snap.fast_stop),
        "part": snap.part,
        "part_inside": _part_inside(gripper),
        "blocked_at": snap.blocked_at,
        "faults": on,
        "net": _net_state(gripper),
        "statistics": list(snap.statistics),
    }


def _part_inside(gripper: Any) -> bool | None:
    """True for a ring gripped from inside, False for a part gripped from outside, None without a part."""
    part = getattr(gripper, "obstacles", {}).get("part")
    return None if part is None else part.blocks > 0


def _net_state(gripper: Any) -> dict[str, Any]:
    from ..server.netfault import net_faults

    return net_faults(gripper).state()


class WorldActions:
    """The world actions as methods, over one ``_apply(action, **params)`` that a front end supplies:
    in process (:class:`pywsg.testing.World`) or over HTTP (:class:`pywsg.testing.remote.RemoteWorld`).

    Widths in mm, stiffness in N/mm, ``delta_c`` in °C, durations in s. Each returns what was done, in words.
    """

    def _apply(self, action: str, **params: Any) -> str:
        raise NotImplementedError

    def place_part(self, width: float, stiffness: float | None = None, inside: bool = False) -> str:
        """Put a part of ``width`` mm in the gripper: between the fingers, gripped from outside (the
        default), or with ``inside=True`` a ring around them, gripped from inside. ``stiffness`` N/mm
        (default rigid: a held part reads its own width)."""
        return self._apply("part", width=width, stiffness=stiffness, inside=inside)

    def remove_part(self) -> str:
        """Take the part away (while HOLDING: the part is lost)."""
        return self._apply("remove_part")

    def block(self, width: float) -> str:
        """Put a rigid obstacle in the fingers' way at ``width`` mm."""
        return self._apply("block", width=width)

    def unblock(self) -> str:
        return self._apply("unblock")

    def fault(self, kind: str, on: bool = True, finger: int | None = None, timeout: float | None = None) -> str:
        """Switch a fault on or off: ``kind`` power, current, finger (over-current, ``finger`` 1 or 2),
        ack (acknowledge refused), watchdog (FAST STOP ``timeout`` s without a request) or unplugged
        (``finger`` 1 or 2); what each reports: docs/testing.md, "World faults"."""
        params: dict[str, Any] = {"kind": kind, "on": on}
        if finger is not None:
            params["finger"] = finger
        if timeout is not None:
            params["timeout"] = timeout
        return self._apply("fault", **params)

    def slip(self, duration: float = 1.0) -> str:
        """The part slides out of the fingers; ``duration`` s (gripper clock) later it is gone (PART LOST)."""
        return self._apply("slip", duration=duration)

    def disconnect(self) -> str:
        """The gripper closes its TCP connections (FIN); the sessions end without 07h: FAST STOP."""
        return self._apply("disconnect")

    def net(self, kind: str, on: bool = True, **params: Any) -> str:
        """Switch a network fault on (with its parameters) or off, at once, on every interface of this
        gripper: ``latency`` (ms, jitter ms), ``bandwidth`` (rate bytes/s), ``slicer`` (size bytes, gap
        ms), ``reset`` (timeout s), ``silent`` (timeout s), ``drop`` / ``reorder`` / ``garble`` (p);
        ``kind="clear"``: all off. See :mod:`pywsg.server.netfault`."""
        return self._apply("net", kind=kind, on=on, **params)

    def heat(self, delta_c: float) -> str:
        """Raise (or lower) the temperature by ``delta_c`` °C at once."""
        return self._apply("heat", delta_c=delta_c)
