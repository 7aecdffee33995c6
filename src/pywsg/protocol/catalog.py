"""The command catalog: one table of every command of the command manual.

Each :class:`CommandSpec` names the command, its request parameters and reply layout (name,
type, unit), and its kind. Encoding and decoding of requests and replies are built from these
tables; the driver, the virtual gripper, the decoder, the CLI and the docs all read them.
"""

from __future__ import annotations

import builtins
import struct
from collections.abc import Mapping
from dataclasses import dataclass, field
from enum import Enum, IntEnum, IntFlag
from typing import Literal, cast

from .flags import (
    AutoUpdateFlag,
    DeviceType,
    FingerFlag,
    FingerType,
    GripperState,
    HomingDirection,
    PrepositionFlag,
    SystemFlag,
)
from .frame import MAX_PAYLOAD
from .status import Status

FieldType = Literal["u8", "u16", "u32", "i16", "f32", "bytes", "str"]
Value = int | float | bytes | str
Values = dict[str, Value]

_FMT: dict[str, str] = {"u8": "B", "u16": "H", "u32": "I", "i16": "h", "f32": "f"}
_SIZES: dict[str, int] = {"u8": 1, "u16": 2, "u32": 4, "i16": 2, "f32": 4}


class Command(IntEnum):
    """Command IDs (command manual chapter 3)."""

    LOOP = 0x06
    DISCONNECT = 0x07
    HOMING = 0x20
    PREPOSITION = 0x21
    STOP = 0x22
    FAST_STOP = 0x23
    ACK_FAST_STOP = 0x24
    GRIP_PART = 0x25
    RELEASE_PART = 0x26
    SET_ACCELERATION = 0x30
    GET_ACCELERATION = 0x31
    SET_FORCE_LIMIT = 0x32
    GET_FORCE_LIMIT = 0x33
    SET_SOFT_LIMITS = 0x34
    GET_SOFT_LIMITS = 0x35
    CLEAR_SOFT_LIMITS = 0x36
    OVERDRIVE_MODE = 0x37
    TARE_FORCE_SENSOR = 0x38
    GET_SYSTEM_STATE = 0x40
    GET_GRIPPER_STATE = 0x41
    GET_GRIPPING_STATISTICS = 0x42
    GET_OPENING_WIDTH = 0x43
    GET_SPEED = 0x44
    GET_FORCE = 0x45
    GET_TEMPERATURE = 0x46
    GET_SYSTEM_INFO = 0x50
    SET_DEVICE_TAG = 0x51
    GET_DEVICE_TAG = 0x52
    GET_SYSTEM_LIMITS = 0x53
    GET_FINGER1_INFO = 0x60
    GET_FINGER1_FLAGS = 0x61
    FINGER1_POWER_CONTROL = 0x62
    GET_FINGER1_DATA = 0x63
    GET_FINGER2_INFO = 0x70
    GET_FINGER2_FLAGS = 0x71
    FINGER2_POWER_CONTROL = 0x72
    GET_FINGER2_DATA = 0x73


class Kind(Enum):
    """How the device answers a command."""

    IMMEDIATE = "immediate"  # one reply
    PENDING = "pending"  # E_CMD_PENDING at once, then one final frame with the same ID
    PENDING_WHEN_ON = "pending when enabling"  # finger power: pending only when switching on


@dataclass(frozen=True, slots=True)
class Field:
    """One parameter. ``bytes``/``str`` fields take the rest of the payload (at most ``max_len``)."""

    name: str
    type: FieldType
    unit: str = ""
    description: str = ""
    enum: builtins.type[Enum] | None = None
    max_len: int = 0

    @property
    def variable(self) -> bool:
        return self.type in ("bytes", "str")

    @property
    def size(self) -> int:
        return _SIZES.get(self.type, 0)


class Layout:
    """A fixed struct part optionally followed by one variable-length field."""

    __slots__ = ("fields", "fixed", "fixed_size", "max_size", "struct", "variable")

    def __init__(self, fields: tuple[Field, ...]) -> None:
        self.fields = fields
        fixed = tuple(f for f in fields if not f.variable)
        var = [f for f in fields if f.variable]
        if len(var) > 1 or (var and fields[-1] is not var[0]):
            raise ValueError("only the last field may be variable-length")
        self.fixed = fixed
        self.variable: Field | None = var[0] if var else None
        self.struct = struct.Struct("<" + "".join(_FMT[f.type] for f in fixed))
        self.fixed_size = self.struct.size
        self.max_size = self.fixed_size + (self.variable.max_len if self.variable else 0)

    def encode(self, values: Mapping[str, Value]) -> bytes:
        args: list[int | float] = []
        for f in self.fixed:
            if f.name not in values:
                raise ValueError(f"missing parameter {f.name!r}")
            v = values[f.name]
            if f.type == "f32":
                if not isinstance(v, int | float):
                    raise TypeError(f"{f.name} must be a number, not {type(v).__name__}")
                args.append(float(v))
            else:
                if not isinstance(v, int):
                    raise TypeError(f"{f.name} must be an integer, not {type(v).__name__}")
                args.append(int(v))
        try:
            out = self.struct.pack(*args)
        except struct.error as exc:
            raise ValueError(f"parameter out of range: {exc}") from None
        if self.variable is not None:
            v = values.get(self.variable.name, b"")
            raw = v.encode("ascii") if isinstance(v, str) else bytes(v)  # type: ignore[arg-type]
            out += raw
        return out

    def decode(self, payload: bytes) -> Values:
        """Decode ``payload``. Raises ValueError when its length does not fit the layout."""
        if self.variable is None:
            if len(payload) != self.fixed_size:
                raise ValueError(f"expected {self.fixed_size} bytes, got {len(payload)}")
        elif len(payload) < self.fixed_size:
            raise ValueError(f"expected at least {self.fixed_size} bytes, got {len(payload)}")
        values: Values = {}
        for f, v in zip(self.fixed, self.struct.unpack_from(payload), strict=True):
            values[f.name] = _to_enum(f, v)
        if self.variable is not None:
            rest = payload[self.fixed_size :]
            if self.variable.type == "str":
                values[self.variable.name] = rest.decode("latin-1")
            else:
                values[self.variable.name] = bytes(rest)
        return values


def _to_enum(f: Field, v: int | float) -> Value:
    if f.enum is not None and isinstance(v, int):
        try:
            return cast(int, f.enum(v))  # the catalog's enums are IntEnum/IntFlag: still ints
        except ValueError:
            return v
    return v


@dataclass(frozen=True)
class CommandSpec:
    """Everything the manual says about one command's wire format."""

    id: int
    name: str
    title: str
    section: str
    description: str
    request: tuple[Field, ...] = ()
    reply: tuple[Field, ...] = ()
    kind: Kind = Kind.IMMEDIATE
    auto_update: bool = False
    motion: bool = False
    statuses: tuple[Status, ...] = (Status.E_SUCCESS,)
    request_layout: Layout = field(init=False, repr=False, compare=False)
    reply_layout: Layout = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "request_layout", Layout(self.request))
        object.__setattr__(self, "reply_layout", Layout(self.reply))

    @property
    def label(self) -> str:
        """``HOMING (20h)``."""
        return f"{self.name} ({self.id:02X}h)"

    @property
    def max_request_size(self) -> int:
        """Largest payload the device accepts for this ID before it answers a format error.

        Variable-length requests may carry more than their limit (Loop: 256 bytes, tag: 64
        characters) so the device can answer E_OVERRUN / E_CMD_FORMAT_ERROR; the parser's
        1 KiB cap still holds.
        """
        if self.request_layout.variable is not None:
            return MAX_PAYLOAD
        return self.request_layout.fixed_size

    def encode_request(self, values: Mapping[str, Value] | None = None, **kw: Value) -> bytes:
        """Request payload from parameter values (by the manual's names, lower case)."""
        merged = dict(values or {}, **kw)
        return self.request_layout.encode(merged)

    def decode_request(self, payload: bytes) -> Values:
        return self.request_layout.decode(payload)

    def encode_reply(self, status: Status | int = Status.E_SUCCESS, values: Mapping[str, Value] | None = None,
                     **kw: Value) -> bytes:
        """Reply payload: status, then the reply parameters (only for E_SUCCESS)."""
        head = struct.pack("<H", int(status))
        if int(status) != Status.E_SUCCESS:
            return head
        return head + self.reply_layout.encode(dict(values or {}, **kw))

    def decode_reply(self, payload: bytes) -> tuple[Status | int, Values]:
        """(status, values). Values are decoded only for E_SUCCESS with a matching length."""
        if len(payload) < 2:
            raise ValueError(f"reply of {len(payload)} bytes has no status code")
        code = payload[0] | (payload[1] << 8)
        try:
            status: Status | int = Status(code)
        except ValueError:
            status = code
        if code != Status.E_SUCCESS or (len(payload) == 2 and not self.reply):
            return status, {}
        return status, self.reply_layout.decode(payload[2:])


def _auto_update_request() -> tuple[Field, ...]:
    return (
        Field("flags", "u8", "", "D0 automatic update, D1 update on change only", AutoUpdateFlag),
        Field("period_ms", "u16", "ms", "minimum period between automatic packets (>= 10 ms)"),
    )


_F = Status
_MOTION_IMMEDIATE = (_F.E_ACCESS_DENIED, _F.E_ALREADY_RUNNING, _F.E_CMD_FORMAT_ERROR, _F.E_CMD_PENDING)
# pywsg adds E_INVALID_PARAMETER: PERIOD_MS below the manual's minimum of 10 ms
_AUTO_UPDATE_STATUSES = (_F.E_SUCCESS, _F.E_CMD_FORMAT_ERROR, _F.E_INVALID_PARAMETER)


def _finger_commands(n: int, base: int) -> list[CommandSpec]:
    return [
        CommandSpec(
            base, f"GET_FINGER{n}_INFO", f"Get Finger {n} Info", f"3.6.{1 + 4 * (n - 1)}",
            "Type of the connected finger and the size of one data frame.",
            reply=(
                Field("type", "u8", "", "finger type", FingerType),
                Field("size", "u16", "bytes", "size of one data frame of Get Finger Data (0: none)"),
            ),
            statuses=(_F.E_SUCCESS, _F.E_CMD_FORMAT_ERROR, _F.E_INSUFFICIENT_RESOURCES),
        ),
        CommandSpec(
            base + 1, f"GET_FINGER{n}_FLAGS", f"Get Finger {n} Flags", f"3.6.{2 + 4 * (n - 1)}",
            "State flags of the finger.",
            reply=(Field("flags", "u16", "", "finger flags", FingerFlag),),
            statuses=(_F.E_SUCCESS, _F.E_CMD_FORMAT_ERROR, _F.E_INSUFFICIENT_RESOURCES),
        ),
        CommandSpec(
            base + 2, f"FINGER{n}_POWER_CONTROL", f"Finger {n} Power Control", f"3.6.{3 + 4 * (n - 1)}",
            "Switch the finger's power supply (generic fingers only). Enabling answers E_CMD_PENDING, "
            "then E_SUCCESS after about 500 ms.",
            request=(Field("power", "u8", "", "0: off, 1: on"),),
            kind=Kind.PENDING_WHEN_ON,
            # pywsg adds: E_INVALID_PARAMETER (ON/OFF not 0 or 1), E_ACCESS_DENIED (a predefined finger "can
            # not be activated or deactivated"), E_ALREADY_RUNNING (still powering up)
            statuses=(_F.E_SUCCESS, _F.E_CMD_FORMAT_ERROR, _F.E_CMD_FAILED, _F.E_CMD_PENDING,
                      _F.E_INVALID_PARAMETER, _F.E_ACCESS_DENIED, _F.E_ALREADY_RUNNING),
        ),
        CommandSpec(
            base + 3, f"GET_FINGER{n}_DATA", f"Get Finger {n} Data", f"3.6.{4 + 4 * (n - 1)}",
            "Current finger data for predefined finger types (layout depends on the finger).",
            reply=(Field("data", "bytes", "", "finger-specific data frame", max_len=MAX_PAYLOAD),),
            statuses=(_F.E_SUCCESS, _F.E_CMD_FORMAT_ERROR, _F.E_IO_ERROR, _F.E_NOT_AVAILABLE),
        ),
    ]


_SPECS: list[CommandSpec] = [
    CommandSpec(
        Command.LOOP, "LOOP", "Loop", "3.1.1", "Returns the received payload (at most 256 bytes).",
        request=(Field("data", "bytes", "", "payload to be looped", max_len=256),),
        reply=(Field("data", "bytes", "", "the looped payload", max_len=256),),
        statuses=(_F.E_SUCCESS, _F.E_CMD_FORMAT_ERROR, _F.E_INVALID_PARAMETER),
    ),
    CommandSpec(
        Command.DISCONNECT, "DISCONNECT", "Disconnect Announcement", "3.1.2",
        "Announce a regular disconnection (TCP only): no FAST STOP when the connection closes.",
        statuses=(_F.E_SUCCESS, _F.E_NO_PARAM_EXPECTED, _F.E_NOT_AVAILABLE),
    ),
    CommandSpec(
        Command.HOMING, "HOMING", "Homing", "3.2.1",
        "Reference the fingers by moving to the mechanical end stop (soft limits ignored).",
        request=(Field("direction", "u8", "", "0: default, 1: positive, 2: negative", HomingDirection),),
        kind=Kind.PENDING, motion=True,
        statuses=(*_MOTION_IMMEDIATE, _F.E_INVALID_PARAMETER, _F.E_SUCCESS, _F.E_CMD_ABORTED,
                  _F.E_AXIS_BLOCKED, _F.E_TIMEOUT),
    ),
    CommandSpec(
        Command.PREPOSITION, "PREPOSITION", "Pre-position Fingers", "3.2.2",
        "Move the fingers to an opening width (absolute or relative; stop or clamp on block).",
        request=(
            Field("flags", "u8", "", "D0 relative motion, D1 stop on block", PrepositionFlag),
            Field("width", "f32", "mm", "opening width"),
            Field("speed", "f32", "mm/s", "travelling speed"),
        ),
        kind=Kind.PENDING, motion=True,
        statuses=(*_MOTION_IMMEDIATE, _F.E_NOT_INITIALIZED, _F.E_RANGE_ERROR, _F.E_SUCCESS,
                  _F.E_INSUFFICIENT_RESOURCES, _F.E_AXIS_BLOCKED, _F.E_TIMEOUT, _F.E_CMD_ABORTED,
                  _F.E_INVALID_PARAMETER),  # pywsg adds E_INVALID_PARAMETER: a NaN or infinite WIDTH/SPEED
    ),
    CommandSpec(
        Command.STOP, "STOP", "Stop", "3.2.3", "Stop any finger movement; sets SF_AXIS_STOPPED.",
        statuses=(_F.E_SUCCESS, _F.E_NO_PARAM_EXPECTED, _F.E_TIMEOUT),
    ),
    CommandSpec(
        Command.FAST_STOP, "FAST_STOP", "Issue FAST STOP", "3.2.4",
        "Emergency stop: motion commands are refused until the FAST STOP is acknowledged.",
        statuses=(_F.E_SUCCESS,),
    ),
    CommandSpec(
        Command.ACK_FAST_STOP, "ACK_FAST_STOP", "Acknowledge FAST STOP", "3.2.5",
        "Acknowledge a FAST STOP or fault condition with the key \"ack\".",
        request=(Field("key", "str", "", "the letters \"ack\"", max_len=3),),
        # pywsg adds E_ACCESS_DENIED: a power or current fault persists (App. B D16/D17: the FAST STOP
        # can be acknowledged only once the fault has cleared)
        statuses=(_F.E_SUCCESS, _F.E_CMD_FORMAT_ERROR, _F.E_ACCESS_DENIED),
    ),
    CommandSpec(
        Command.GRIP_PART, "GRIP_PART", "Grip Part", "3.2.6",
        "Grip a part of a nominal width with the set force limit, within the clamping travel.",
        request=(Field("width", "f32", "mm", "nominal part width"), Field("speed", "f32", "mm/s", "gripping speed")),
        kind=Kind.PENDING, motion=True,
        statuses=(*_MOTION_IMMEDIATE, _F.E_RANGE_ERROR, _F.E_SUCCESS, _F.E_CMD_ABORTED, _F.E_CMD_FAILED,
                  _F.E_TIMEOUT, _F.E_NOT_INITIALIZED, _F.E_INVALID_PARAMETER),  # pywsg adds the last two
    ),
    CommandSpec(
        Command.RELEASE_PART, "RELEASE_PART", "Release Part", "3.2.7",
        "Release a gripped part by opening to an absolute width.",
        request=(Field("width", "f32", "mm", "opening width"), Field("speed", "f32", "mm/s", "opening speed")),
        kind=Kind.PENDING, motion=True,
        statuses=(*_MOTION_IMMEDIATE, _F.E_RANGE_ERROR, _F.E_SUCCESS, _F.E_CMD_ABORTED, _F.E_TIMEOUT,
                  _F.E_NOT_INITIALIZED, _F.E_INVALID_PARAMETER),  # pywsg adds the last two
    ),
    CommandSpec(
        Command.SET_ACCELERATION, "SET_ACCELERATION", "Set Acceleration", "3.3.1",
        "Acceleration for following motions (clamped to the device limits; session only).",
        request=(Field("acceleration", "f32", "mm/s²", "acceleration"),),
        statuses=(_F.E_SUCCESS, _F.E_CMD_FORMAT_ERROR, _F.E_INVALID_PARAMETER),  # pywsg adds E_INVALID_PARAMETER
    ),
    CommandSpec(
        Command.GET_ACCELERATION, "GET_ACCELERATION", "Get Acceleration", "3.3.2", "The set acceleration.",
        reply=(Field("acceleration", "f32", "mm/s²", "acceleration"),),
        statuses=(_F.E_SUCCESS, _F.E_NO_PARAM_EXPECTED),
    ),
    CommandSpec(
        Command.SET_FORCE_LIMIT, "SET_FORCE_LIMIT", "Set Force Limit", "3.3.3",
        "Gripping force limit (clamped to minimum and nominal, or overdrive, force; session only).",
        request=(Field("force", "f32", "N", "force limit"),),
        statuses=(_F.E_SUCCESS, _F.E_CMD_FORMAT_ERROR, _F.E_INVALID_PARAMETER),  # pywsg adds E_INVALID_PARAMETER
    ),
    CommandSpec(
        Command.GET_FORCE_LIMIT, "GET_FORCE_LIMIT", "Get Force Limit", "3.3.4", "The set force limit.",
        reply=(Field("force", "f32", "N", "force limit"),),
        statuses=(_F.E_SUCCESS, _F.E_NO_PARAM_EXPECTED),
    ),
    CommandSpec(
        Command.SET_SOFT_LIMITS, "SET_SOFT_LIMITS", "Set Soft Limits", "3.3.5",
        "Soft limits in minus and plus direction (session only).",
        request=(Field("minus", "f32", "mm", "soft limit in negative direction"),
                 Field("plus", "f32", "mm", "soft limit in positive direction")),
        statuses=(_F.E_SUCCESS, _F.E_CMD_FORMAT_ERROR, _F.E_INVALID_PARAMETER),  # pywsg adds E_INVALID_PARAMETER
    ),
    CommandSpec(
        Command.GET_SOFT_LIMITS, "GET_SOFT_LIMITS", "Get Soft Limits", "3.3.6",
        "The soft limits; E_NOT_AVAILABLE when none are set.",
        reply=(Field("minus", "f32", "mm", "soft limit in negative direction"),
               Field("plus", "f32", "mm", "soft limit in positive direction")),
        statuses=(_F.E_SUCCESS, _F.E_NOT_AVAILABLE, _F.E_INSUFFICIENT_RESOURCES, _F.E_NO_PARAM_EXPECTED),
    ),
    CommandSpec(
        Command.CLEAR_SOFT_LIMITS, "CLEAR_SOFT_LIMITS", "Clear Soft Limits", "3.3.7", "Clear the soft limits.",
        statuses=(_F.E_SUCCESS, _F.E_NO_PARAM_EXPECTED),
    ),
    CommandSpec(
        Command.OVERDRIVE_MODE, "OVERDRIVE_MODE", "Overdrive Mode", "3.3.8",
        "Enable or disable force overdrive (force limit up to the overdrive force).",
        request=(Field("flags", "u8", "", "D0: 1 enable, 0 disable"),),
        statuses=(_F.E_SUCCESS, _F.E_CMD_FORMAT_ERROR, _F.E_INVALID_PARAMETER),  # pywsg adds E_INVALID_PARAMETER
    ),
    CommandSpec(
        Command.TARE_FORCE_SENSOR, "TARE_FORCE_SENSOR", "Tare Force Sensor", "3.3.9",
        "Zero the force sensor (not while HOLDING).",
        statuses=(_F.E_SUCCESS, _F.E_NOT_AVAILABLE, _F.E_ACCESS_DENIED, _F.E_NO_PARAM_EXPECTED),
    ),
    CommandSpec(
        Command.GET_SYSTEM_STATE, "GET_SYSTEM_STATE", "Get System State", "3.4.1",
        "System state flags (Appendix B); auto-update capable.",
        request=_auto_update_request(),
        reply=(Field("state", "u32", "", "system state flags", SystemFlag),),
        auto_update=True, statuses=_AUTO_UPDATE_STATUSES,
    ),
    CommandSpec(
        Command.GET_GRIPPER_STATE, "GET_GRIPPER_STATE", "Get Gripper State", "3.4.2",
        "Grasping state (0 IDLE .. 7 ERROR); auto-update capable.",
        request=_auto_update_request(),
        reply=(Field("state", "u8", "", "grasping state", GripperState),),
        auto_update=True, statuses=_AUTO_UPDATE_STATUSES,
    ),
    CommandSpec(
        Command.GET_GRIPPING_STATISTICS, "GET_GRIPPING_STATISTICS", "Get Gripping Statistics", "3.4.3",
        "Number of grips, grips with no part found and parts lost.",
        request=(Field("flags", "u8", "", "D0: reset statistics after reading"),),
        reply=(Field("total", "u32", "grips", "total grips"), Field("no_part", "u16", "grips", "no part found"),
               Field("lost_part", "u16", "grips", "part lost")),
        statuses=(_F.E_SUCCESS, _F.E_CMD_FORMAT_ERROR),
    ),
    CommandSpec(
        Command.GET_OPENING_WIDTH, "GET_OPENING_WIDTH", "Get Opening Width", "3.4.4",
        "Finger opening width; auto-update capable (change: 0.01 mm).",
        request=_auto_update_request(), reply=(Field("width", "f32", "mm", "opening width"),),
        auto_update=True, statuses=_AUTO_UPDATE_STATUSES,
    ),
    CommandSpec(
        Command.GET_SPEED, "GET_SPEED", "Get Speed", "3.4.5",
        "Relative finger speed; auto-update capable (change: 0.05 mm/s).",
        request=_auto_update_request(), reply=(Field("speed", "f32", "mm/s", "finger speed"),),
        auto_update=True, statuses=_AUTO_UPDATE_STATUSES,
    ),
    CommandSpec(
        Command.GET_FORCE, "GET_FORCE", "Get Force", "3.4.6",
        "Gripping force; auto-update capable (change: 0.05 N).",
        request=_auto_update_request(), reply=(Field("force", "f32", "N", "gripping force"),),
        auto_update=True, statuses=_AUTO_UPDATE_STATUSES,
    ),
    CommandSpec(
        Command.GET_TEMPERATURE, "GET_TEMPERATURE", "Get Temperature", "3.4.7", "Device temperature.",
        reply=(Field("temperature", "i16", "0.1 °C", "temperature in tenths of a degree Celsius"),),
        statuses=(_F.E_SUCCESS, _F.E_NO_PARAM_EXPECTED, _F.E_INSUFFICIENT_RESOURCES),
    ),
    CommandSpec(
        Command.GET_SYSTEM_INFO, "GET_SYSTEM_INFO", "Get System Information", "3.5.1",
        "Device type, hardware revision, firmware version and serial number.",
        reply=(
            Field("type", "u8", "", "device type", DeviceType),
            Field("hwrev", "u8", "", "hardware revision"),
            Field("fw_version", "u16", "", "D15..12 major, D11..8 minor 1, D7..4 minor 2, D3..0 RC"),
            Field("sn", "u32", "", "serial number"),
        ),
        statuses=(_F.E_SUCCESS, _F.E_NO_PARAM_EXPECTED, _F.E_INSUFFICIENT_RESOURCES),
    ),
    CommandSpec(
        Command.SET_DEVICE_TAG, "SET_DEVICE_TAG", "Set Device Tag", "3.5.2",
        "Set the device tag (at most 64 printable characters).",
        request=(Field("tag", "str", "", "device tag", max_len=64),),
        statuses=(_F.E_SUCCESS, _F.E_OVERRUN, _F.E_INVALID_PARAMETER, _F.E_INSUFFICIENT_RESOURCES),
    ),
    CommandSpec(
        Command.GET_DEVICE_TAG, "GET_DEVICE_TAG", "Get Device Tag", "3.5.3",
        "The device tag; E_NOT_AVAILABLE when none is set.",
        reply=(Field("tag", "str", "", "device tag", max_len=64),),
        statuses=(_F.E_SUCCESS, _F.E_NO_PARAM_EXPECTED, _F.E_NOT_AVAILABLE, _F.E_INSUFFICIENT_RESOURCES),
    ),
    CommandSpec(
        Command.GET_SYSTEM_LIMITS, "GET_SYSTEM_LIMITS", "Get System Limits", "3.5.4",
        "Stroke, speed, acceleration and force limits.",
        reply=(
            Field("stroke", "f32", "mm", "gripper stroke"),
            Field("min_speed", "f32", "mm/s", "minimum speed"),
            Field("max_speed", "f32", "mm/s", "maximum speed"),
            Field("min_acc", "f32", "mm/s²", "minimum acceleration"),
            Field("max_acc", "f32", "mm/s²", "maximum acceleration"),
            Field("min_force", "f32", "N", "minimum grasping force"),
            Field("nom_force", "f32", "N", "nominal grasping force"),
            Field("ovr_force", "f32", "N", "maximum overdrive grasping force"),
        ),
        statuses=(_F.E_SUCCESS, _F.E_NO_PARAM_EXPECTED, _F.E_INSUFFICIENT_RESOURCES),
    ),
    *_finger_commands(1, Command.GET_FINGER1_INFO),
    *_finger_commands(2, Command.GET_FINGER2_INFO),
]

CATALOG: dict[int, CommandSpec] = {spec.id: spec for spec in _SPECS}
"""Every command of the manual by ID."""


def spec_for(command_id: int) -> CommandSpec | None:
    """The catalog entry for ``command_id`` or None for unknown IDs."""
    return CATALOG.get(command_id)


def command_name(command_id: int) -> str:
    spec = CATALOG.get(command_id)
    return spec.name if spec else f"UNKNOWN_{command_id:02X}h"


def request_max_payload(command_id: int) -> int:
    """Device-side SIZE cap for the parser: the largest valid request for a known ID, else 1 KiB."""
    spec = CATALOG.get(command_id)
    return spec.max_request_size if spec else MAX_PAYLOAD


def format_value(value: Value, fld: Field) -> str:
    """Human form of a decoded value with its unit."""
    if isinstance(value, IntFlag):
        names = [m.name for m in type(value) if m.value and m.name and value & m]
        return f"0x{int(value):X} [{', '.join(names) or '-'}]"
    if isinstance(value, IntEnum):
        return f"{value.name} ({int(value)})"
    if isinstance(value, float):
        return f"{value:.4g} {fld.unit}".rstrip()
    if isinstance(value, bytes):
        return value.hex(" ").upper() or "(empty)"
    if isinstance(value, str):
        return repr(value)
    return f"{value} {fld.unit}".rstrip()
