"""One request description per catalog command, shared by :class:`AsyncGripper` and :class:`Gripper`.

A :class:`Call` holds the whole request frame (encoded through the catalog) and how to turn the
reply's decoded values into the method's result. The two shells only move bytes.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from functools import cache
from typing import Any, Generic, TypeVar, cast

from ..protocol import (
    CATALOG,
    AutoUpdateFlag,
    Command,
    DeviceType,
    FingerFlag,
    FingerType,
    GripperState,
    HomingDirection,
    Kind,
    PrepositionFlag,
    Status,
    SystemFlag,
    Values,
    encode_frame,
)
from .types import FingerInfo, Limits, SoftLimits, Statistics, SystemInfo

T = TypeVar("T")

AUTO_UPDATE_IDS = (Command.GET_SYSTEM_STATE, Command.GET_GRIPPER_STATE, Command.GET_OPENING_WIDTH,
                   Command.GET_SPEED, Command.GET_FORCE)
STREAM_NAMES: dict[str, Command] = {
    "system_state": Command.GET_SYSTEM_STATE,
    "gripper_state": Command.GET_GRIPPER_STATE,
    "width": Command.GET_OPENING_WIDTH,
    "speed": Command.GET_SPEED,
    "force": Command.GET_FORCE,
}


@dataclass(frozen=True, slots=True)
class Call(Generic[T]):
    """A request frame and the decoding of its successful reply."""

    command_id: int
    wire: bytes
    decode: Callable[[Values], T]
    pending: bool = False  # may answer E_CMD_PENDING and later a final frame
    motion: bool = False  # read the system flags when it fails (FAST STOP? blocked?)
    none_on: frozenset[int] = field(default_factory=frozenset)  # statuses that mean "no value": result None
    raw: bool = False  # custom request: the result is a Reply, errors are the caller's choice
    auto_read: bool = False  # a one-off read of an auto-update value (flags 0: it would end a subscription)
    fast: Callable[[bytes], T] | None = None  # whole reply payload (status included) -> result, fixed layouts
    # payload -> result for calls whose results are immutable (floats, ints, flags): decoded once
    memo: dict[bytes, T] | None = field(default=None, compare=False, hash=False)


def _none(_v: Values) -> None:
    return None


def _make(cmd: Command, decode: Callable[[Values], T], none_on: frozenset[int] = frozenset(),
          auto_read: bool = False, memo: bool = False, **values: Any) -> Call[T]:
    """``memo``: the result is immutable (a number or flags), so it may be decoded once per payload."""
    spec = CATALOG[cmd]
    payload = spec.encode_request(values) if spec.request else b""
    fast = _fast_decoder(spec, decode)
    return Call(int(cmd), encode_frame(int(cmd), payload), decode, pending=spec.kind is not Kind.IMMEDIATE,
                motion=spec.motion, none_on=none_on, auto_read=auto_read, fast=fast,
                memo={} if memo and fast is not None else None)


def _fast_decoder(spec: Any, decode: Callable[[Values], T]) -> Callable[[bytes], T] | None:
    """One struct.unpack_from for fixed reply layouts (the hot path of state reads); the decoders
    of 40h/41h convert their enums themselves. Raises ValueError on a wrong length."""
    layout = spec.reply_layout
    if layout.variable is not None or any(f.enum not in (None, SystemFlag, GripperState) for f in layout.fixed):
        return None
    st = layout.struct
    size = 2 + st.size
    names = tuple(f.name for f in layout.fixed)

    def fast(payload: bytes) -> T:
        if len(payload) != size:
            raise ValueError(f"expected {size - 2} bytes, got {len(payload) - 2}")
        return decode(dict(zip(names, st.unpack_from(payload, 2), strict=True)))
    return fast


def _float(name: str) -> Callable[[Values], float]:
    def dec(v: Values) -> float:
        return float(cast(float, v[name]))
    return dec


def check_speed(speed: float, what: str = "speed") -> float:
    if not speed > 0:
        raise ValueError(f"{what} must be > 0 (mm/s), not {speed!r}")
    return float(speed)


# -- connection
def loop(data: bytes) -> Call[bytes]:
    return _make(Command.LOOP, lambda v: cast(bytes, v["data"]), data=bytes(data))


@cache
def disconnect() -> Call[None]:
    return _make(Command.DISCONNECT, _none)


# -- motion
def homing(direction: HomingDirection | int | str | None) -> Call[None]:
    if direction is None:
        d = HomingDirection.DEFAULT
    elif isinstance(direction, str):
        d = HomingDirection[direction.upper()]
    else:
        d = HomingDirection(direction)
    return _make(Command.HOMING, _none, direction=int(d))


def preposition(width: float, speed: float, relative: bool, stop_on_block: bool) -> Call[None]:
    flags = (PrepositionFlag.RELATIVE if relative else 0) | (PrepositionFlag.STOP_ON_BLOCK if stop_on_block else 0)
    return _make(Command.PREPOSITION, _none, flags=int(flags), width=float(width), speed=check_speed(speed))


@cache
def stop() -> Call[None]:
    return _make(Command.STOP, _none)


@cache
def fast_stop() -> Call[None]:
    return _make(Command.FAST_STOP, _none)


@cache
def acknowledge() -> Call[None]:
    return _make(Command.ACK_FAST_STOP, _none, key="ack")


def grip(width: float, speed: float) -> Call[None]:
    return _make(Command.GRIP_PART, _none, width=float(width), speed=check_speed(speed))


def release(width: float, speed: float) -> Call[None]:
    return _make(Command.RELEASE_PART, _none, width=float(width), speed=check_speed(speed))


# -- motion configuration
def set_acceleration(acceleration: float) -> Call[None]:
    return _make(Command.SET_ACCELERATION, _none, acceleration=float(acceleration))


@cache
def acceleration() -> Call[float]:
    return _make(Command.GET_ACCELERATION, _float("acceleration"), memo=True)


def set_force_limit(force: float) -> Call[None]:
    return _make(Command.SET_FORCE_LIMIT, _none, force=float(force))


@cache
def force_limit() -> Call[float]:
    return _make(Command.GET_FORCE_LIMIT, _float("force"), memo=True)


def set_soft_limits(minus: float, plus: float) -> Call[None]:
    return _make(Command.SET_SOFT_LIMITS, _none, minus=float(minus), plus=float(plus))


@cache
def soft_limits() -> Call[SoftLimits | None]:
    def dec(v: Values) -> SoftLimits | None:
        return SoftLimits(float(cast(float, v["minus"])), float(cast(float, v["plus"])))
    return _make(Command.GET_SOFT_LIMITS, dec, none_on=frozenset({Status.E_NOT_AVAILABLE}))


@cache
def clear_soft_limits() -> Call[None]:
    return _make(Command.CLEAR_SOFT_LIMITS, _none)


@cache
def overdrive(enable: bool) -> Call[None]:
    return _make(Command.OVERDRIVE_MODE, _none, flags=1 if enable else 0)


@cache
def tare() -> Call[None]:
    return _make(Command.TARE_FORCE_SENSOR, _none)


# -- state (auto-update capable: flags 0 = one reading)
def _read_flags(auto: bool, change_only: bool) -> int:
    return int((AutoUpdateFlag.AUTO_UPDATE if auto else 0) | (AutoUpdateFlag.CHANGE_ONLY if change_only else 0))


def _gstate(v: Values) -> GripperState | int:
    x = v["state"]
    if isinstance(x, GripperState):
        return x
    try:
        return GripperState(cast(int, x))
    except ValueError:
        return cast(int, x)


def decode_sample(cmd: int, v: Values) -> SystemFlag | GripperState | float | int:
    if cmd == Command.GET_SYSTEM_STATE:
        return SystemFlag(cast(int, v["state"]))
    if cmd == Command.GET_GRIPPER_STATE:
        return _gstate(v)
    return float(cast(float, v[CATALOG[cmd].reply[0].name]))


@cache
def system_state() -> Call[SystemFlag]:
    return _make(Command.GET_SYSTEM_STATE, lambda v: SystemFlag(cast(int, v["state"])), flags=0, period_ms=0,
                 auto_read=True, memo=True)


@cache
def gripper_state() -> Call[GripperState | int]:
    return _make(Command.GET_GRIPPER_STATE, _gstate, flags=0, period_ms=0, auto_read=True, memo=True)


@cache
def width() -> Call[float]:
    return _make(Command.GET_OPENING_WIDTH, _float("width"), flags=0, period_ms=0, auto_read=True, memo=True)


@cache
def speed() -> Call[float]:
    return _make(Command.GET_SPEED, _float("speed"), flags=0, period_ms=0, auto_read=True, memo=True)


@cache
def force() -> Call[float]:
    return _make(Command.GET_FORCE, _float("force"), flags=0, period_ms=0, auto_read=True, memo=True)


@cache
def subscribe(cmd: Command, period: float, change_only: bool) -> Call[SystemFlag | GripperState | float | int]:
    period_ms = round(period * 1000)
    if not 10 <= period_ms <= 0xFFFF:
        raise ValueError(f"period must be 0.010 .. 65.535 s, not {period!r}")
    return _make(cmd, lambda v: decode_sample(cmd, v), flags=_read_flags(True, change_only), period_ms=period_ms,
                 memo=True)


@cache
def unsubscribe(cmd: Command) -> Call[None]:
    return _make(cmd, _none, flags=0, period_ms=0)


@cache
def statistics(reset: bool) -> Call[Statistics]:
    def dec(v: Values) -> Statistics:
        return Statistics(cast(int, v["total"]), cast(int, v["no_part"]), cast(int, v["lost_part"]))
    return _make(Command.GET_GRIPPING_STATISTICS, dec, flags=1 if reset else 0)


@cache
def temperature() -> Call[float]:
    return _make(Command.GET_TEMPERATURE, lambda v: cast(int, v["temperature"]) / 10.0, memo=True)


# -- system
@cache
def info() -> Call[SystemInfo]:
    def dec(v: Values) -> SystemInfo:
        return SystemInfo(cast("DeviceType | int", v["type"]), cast(int, v["hwrev"]), cast(int, v["fw_version"]),
                          cast(int, v["sn"]))
    return _make(Command.GET_SYSTEM_INFO, dec)


def set_tag(tag: str) -> Call[None]:
    return _make(Command.SET_DEVICE_TAG, _none, tag=tag)


@cache
def tag() -> Call[str | None]:
    return _make(Command.GET_DEVICE_TAG, lambda v: cast(str, v["tag"]), none_on=frozenset({Status.E_NOT_AVAILABLE}))


@cache
def limits() -> Call[Limits]:
    def dec(v: Values) -> Limits:
        f = [float(cast(float, v[k])) for k in ("stroke", "min_speed", "max_speed", "min_acc", "max_acc",
                                                 "min_force", "nom_force", "ovr_force")]
        return Limits(*f)
    return _make(Command.GET_SYSTEM_LIMITS, dec)


# -- fingers
def _finger_base(n: int) -> int:
    if n not in (1, 2):
        raise ValueError(f"finger must be 1 or 2, not {n!r}")
    return Command.GET_FINGER1_INFO if n == 1 else Command.GET_FINGER2_INFO


@cache
def finger_info(n: int) -> Call[FingerInfo]:
    def dec(v: Values) -> FingerInfo:
        return FingerInfo(cast("FingerType | int", v["type"]), cast(int, v["size"]))
    return _make(Command(_finger_base(n)), dec)


@cache
def finger_flags(n: int) -> Call[FingerFlag]:
    return _make(Command(_finger_base(n) + 1), lambda v: FingerFlag(cast(int, v["flags"])), memo=True)


@cache
def finger_power(n: int, on: bool) -> Call[None]:
    return _make(Command(_finger_base(n) + 2), _none, power=1 if on else 0)


@cache
def finger_data(n: int) -> Call[bytes]:
    return _make(Command(_finger_base(n) + 3), lambda v: cast(bytes, v["data"]))


def raw(command_id: int, payload: bytes) -> Call[bytes]:
    """A custom request: any ID (e.g. an on-board script's), the result is the reply's parameter bytes."""
    if not 0 <= command_id <= 0xFF:
        raise ValueError(f"command ID {command_id} is not a byte")
    spec = CATALOG.get(command_id)
    return Call(command_id, encode_frame(command_id, bytes(payload)), lambda _v: b"",
                pending=True, motion=bool(spec and spec.motion), raw=True)
