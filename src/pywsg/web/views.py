"""Plain data for the pages: snapshots, flags, settings forms, as JSON-ready dicts.

Nothing here touches I/O; the app turns these into responses and WebSocket messages.
"""

from __future__ import annotations

import dataclasses
import enum
import importlib
import math
import typing
from collections.abc import Mapping
from typing import Any

from ..protocol import GripperState, SystemFlag

# The order and wording of the screenshot's right column (fieldbus manual 003, figure 1).
FLAG_LABELS: list[tuple[SystemFlag, str]] = [
    (SystemFlag.SF_REFERENCED, "Referenced"),
    (SystemFlag.SF_MOVING, "Moving"),
    (SystemFlag.SF_BLOCKED_MINUS, "Blocked Minus"),
    (SystemFlag.SF_BLOCKED_PLUS, "Blocked Plus"),
    (SystemFlag.SF_SOFT_LIMIT_MINUS, "Soft Limit Minus"),
    (SystemFlag.SF_SOFT_LIMIT_PLUS, "Soft Limit Plus"),
    (SystemFlag.SF_AXIS_STOPPED, "Axis stopped"),
    (SystemFlag.SF_TARGET_POS_REACHED, "Target Pos reached"),
    (SystemFlag.SF_OVERDRIVE_MODE, "Overdrive Mode"),
    (SystemFlag.SF_FORCECNTL_MODE, "Force Control Mode"),
    (SystemFlag.SF_FAST_STOP, "Fast Stop"),
    (SystemFlag.SF_TEMP_WARNING, "Temperature Warning"),
    (SystemFlag.SF_TEMP_FAULT, "Temperature Fault"),
    (SystemFlag.SF_POWER_FAULT, "Power Fault"),
    (SystemFlag.SF_CURR_FAULT, "Current Fault"),
    (SystemFlag.SF_FINGER_FAULT, "Finger Fault"),
    (SystemFlag.SF_CMD_FAILURE, "Command Failure"),
    (SystemFlag.SF_SCRIPT_RUNNING, "Script is running"),
    (SystemFlag.SF_SCRIPT_FAILURE, "Script Failure"),
]


# plain ints: IntFlag arithmetic costs ~7 µs per test, and this runs for every live update
_FLAG_BITS: list[tuple[int, str, str]] = [(int(f), str(f.name), label) for f, label in FLAG_LABELS]


def jsonable(value: Any) -> Any:
    """Convert snapshot/settings values to JSON: enums by name, flags as ints, NaN/inf as None."""
    if type(value) in (int, float, str, bool) or value is None:  # fast path: most snapshot fields
        return value if type(value) is not float or math.isfinite(value) else None
    if isinstance(value, enum.IntFlag):
        return int(value)
    if isinstance(value, enum.Enum):
        return value.value if isinstance(value, str) else value.name
    if isinstance(value, bool | int | str) or value is None:
        return value
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {f.name: jsonable(getattr(value, f.name)) for f in dataclasses.fields(value)}
    if isinstance(value, Mapping):
        return {str(k): jsonable(v) for k, v in value.items()}
    if isinstance(value, list | tuple | set | frozenset):
        return [jsonable(v) for v in value]
    if hasattr(value, "_asdict"):
        return jsonable(value._asdict())
    return str(value)


def state_view(snapshot: Any) -> dict[str, Any]:
    """The Control Panel's data: every snapshot field plus decoded flags and state name.

    Units: width mm, speed mm/s, force N, temperature °C, time s (device clock).
    """
    data: dict[str, Any] = jsonable(snapshot) if dataclasses.is_dataclass(snapshot) else {}
    if not data:
        for name in ("time", "width", "speed", "force", "temperature", "force_limit", "acceleration"):
            if hasattr(snapshot, name):
                data[name] = jsonable(getattr(snapshot, name))
    flags = int(getattr(snapshot, "flags", 0))
    state = getattr(snapshot, "gripper_state", GripperState.IDLE)
    data["flags"] = flags
    data["flag_names"] = [name for bit, name, _ in _FLAG_BITS if flags & bit]
    data["flag_list"] = [{"name": name, "label": label, "on": bool(flags & bit)} for bit, name, label in _FLAG_BITS]
    data["state"] = GripperState(int(state)).name
    return data


# -- settings ---------------------------------------------------------------------------------

# Settings → Command Interface: these fields and any naming an interface; the rest is Motion
# Configuration (device model, homing, clamping travel, defaults, fingers, script).
_INTERFACE_FIELDS = {"crc_check", "fast_stop_on_disconnect", "location", "contact"}
# set by their own command (51h Set Device Tag: Settings → Command Interface has a form for it)
_NOT_IN_FORMS = {"tag"}
_INTERFACE_WORDS = ("tcp", "udp", "crc", "checksum", "port", "interface", "disconnect", "baud", "modbus")

# Labels, units and help for the fields the device's Settings has (pywsg.device.settings).
_KNOWN: dict[str, dict[str, Any]] = {
    "crc_check": {"label": "CRC check", "help": "Evaluate the checksum of received frames (manual 1.4.1). "
                  "Off: frames with a wrong CRC are executed."},
    "fast_stop_on_disconnect": {"label": "FAST STOP on unannounced TCP disconnect",
                                "help": "A TCP client closing without 07h raises FAST STOP (manual 1.4.2)."},
    "homing_direction": {"label": "Homing direction", "choices": [[1, "positive (opening)"],
                                                                 [2, "negative (closing)"]]},
    "clamping_travel": {"label": "Clamping travel", "unit": "mm",
                        "help": "How far the fingers may move beyond the nominal part width while gripping."},
    "default_acceleration": {"label": "Default acceleration", "unit": "mm/s²",
                             "help": "At startup; empty: the model's default."},
    "default_force_limit": {"label": "Default force limit", "unit": "N",
                            "help": "At startup; empty: the model's nominal force."},
    "model": {"label": "Device model"},
    "serial_number": {"label": "Serial number", "help": "50h SN; empty: the model's."},
    "finger1": {"label": "Finger 1 type"},
    "finger2": {"label": "Finger 2 type"},
    "script": {"label": "Script started at power-up", "help": "Firmware plugin; empty: none."},
    "auto_homing": {"label": "Auto-homing on start"},
    "location": {"label": "Location", "help": "Shown in the header (up to 64 characters); empty: n/a."},
    "contact": {"label": "Contact", "help": "Shown in the header (up to 64 characters); empty: n/a."},
}


def _device_choices(name: str) -> list[list[Any]]:
    """Choices the device package knows (models, finger types, plugins); [] when unavailable."""
    try:
        if name == "model":
            from ..device.profiles import PROFILES

            return [[k, getattr(p, "name", k)] for k, p in PROFILES.items()]
        if name in ("finger1", "finger2"):
            from ..device.settings import FINGER_TYPES

            return [[t, t] for t in FINGER_TYPES]
        if name == "script":
            plugins = getattr(importlib.import_module("pywsg.device.plugins"), "PLUGINS", {})
            return [[k, k] for k in plugins]
    except ImportError:
        pass
    return []


def setting_group(name: str) -> str:
    low = name.lower()
    if low in _INTERFACE_FIELDS or any(w in low for w in _INTERFACE_WORDS):
        return "interface"
    return "motion"


def _label(name: str) -> str:
    text = " ".join(w for w in name.split("_") if w)
    return text[:1].upper() + text[1:]


def _kind(tp: Any) -> str:
    """Form input kind of a type annotation: bool, int, float, str or json; ``?`` when optional."""
    origin = typing.get_origin(tp)
    if origin is typing.Union or str(origin) == "<class 'types.UnionType'>":
        args = [a for a in typing.get_args(tp) if a is not type(None)]
        inner = _kind(args[0]) if len(args) == 1 else "json"
        return inner if inner.endswith("?") else inner + "?"
    if isinstance(tp, type):
        if issubclass(tp, bool):
            return "bool"
        if issubclass(tp, enum.Enum):
            return "str"
        if issubclass(tp, int):
            return "int"
        if issubclass(tp, float):
            return "float"
        if issubclass(tp, str):
            return "str"
    return "json"


def settings_schema(settings: Any) -> list[dict[str, Any]]:
    """One entry per settings field: name, label, kind (bool/int/float/str/json, ``?`` = may be
    empty), choices ([value, label] pairs; empty = free input), unit, help, group."""
    cls = type(settings)
    try:
        hints = typing.get_type_hints(cls)
    except Exception:  # unresolvable annotations: fall back to the declared strings
        hints = {}
    out: list[dict[str, Any]] = []
    for f in dataclasses.fields(settings):
        if f.name.startswith("_") or f.name in _NOT_IN_FORMS:
            continue
        known = _KNOWN.get(f.name, {})
        tp = hints.get(f.name, f.type)
        kind = _kind(tp)
        choices: list[list[Any]] = list(known.get("choices", [])) or _device_choices(f.name)
        if not choices and isinstance(tp, type) and issubclass(tp, enum.Enum):
            choices = [[m.name, m.name] for m in tp]
        out.append({
            "name": f.name,
            "label": known.get("label", _label(f.name)),
            "kind": kind,
            "choices": choices,
            "unit": known.get("unit", ""),
            "help": known.get("help", ""),
            "group": setting_group(f.name),
        })
    return out


def coerce_setting(entry: Mapping[str, Any], raw: Any, current: Any) -> Any:
    """Check one submitted value against its form kind; raise ValueError with a short reason.

    JSON types must match (no "12" for a number, no 1 for a checkbox); ``null`` only where the
    field may be empty; choices must be one of the listed values. Range checks are the device's
    (``Settings.validate``).
    """
    kind = str(entry["kind"])
    optional = kind.endswith("?")
    kind = kind.rstrip("?")
    if raw is None or (optional and raw == "" and kind != "str"):
        if optional:
            return None
        raise ValueError("a value is required")
    if kind == "bool":
        if not isinstance(raw, bool):
            raise ValueError("must be true or false")
        value: Any = raw
    elif kind == "int":
        if isinstance(raw, bool) or not isinstance(raw, int):
            raise ValueError("must be a whole number")
        if abs(raw) >= 1 << 63:  # no setting is that large; keeps huge ints away from the device
            raise ValueError("out of range")
        value = raw
    elif kind == "float":
        if isinstance(raw, bool) or not isinstance(raw, int | float):
            raise ValueError("must be a number")
        try:  # a 400-digit integer overflows float() like 1e999 overflows the JSON float
            value = float(raw)
        except OverflowError:
            raise ValueError("must be a finite number") from None
        if not math.isfinite(value):
            raise ValueError("must be a finite number")
    elif kind == "str":
        if not isinstance(raw, str):
            raise ValueError("must be text")
        if len(raw) > 256:
            raise ValueError("at most 256 characters")
        value = raw
        if optional and raw == "":
            return None
    else:
        value = tuple(raw) if isinstance(current, tuple) and isinstance(raw, list) else raw
    choices = entry.get("choices") or []
    if choices and value not in [c[0] for c in choices]:
        raise ValueError("must be one of " + ", ".join(str(c[0]) for c in choices))
    if isinstance(current, enum.Enum) and isinstance(value, str):
        return type(current)[value]
    return value


def field_of_error(message: str, names: list[str]) -> tuple[str, str]:
    """(field, reason) of an ``apply_settings`` ValueError such as ``"clamping_travel: must be …"``."""
    head, sep, rest = message.partition(":")
    if sep and head.strip() in names:
        return head.strip(), rest.strip()
    hits = [n for n in names if n in message]
    return (max(hits, key=len) if hits else "_"), message
