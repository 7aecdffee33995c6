"""Result types of the driver's typed methods (units in the field docs)."""

from __future__ import annotations

from dataclasses import dataclass

from ..protocol import Command, DeviceType, FingerFlag, FingerType, GripperState, Status, SystemFlag


@dataclass(frozen=True, slots=True)
class State:
    """One snapshot of the gripper, read with six pipelined requests (``state()``)."""

    width: float
    """opening width, mm"""
    speed: float
    """finger speed, mm/s"""
    force: float
    """gripping force, N"""
    gripper_state: GripperState | int
    """grasping state (41h)"""
    flags: SystemFlag
    """system state flags (40h)"""
    temperature: float
    """device temperature, °C"""


@dataclass(frozen=True, slots=True)
class SystemInfo:
    """50h Get System Information."""

    type: DeviceType | int
    hardware_revision: int
    firmware_raw: int
    serial_number: int

    @property
    def firmware_version(self) -> str:
        """``major.minor1.minor2`` plus ``-rcN`` when the RC nibble is set (D15..12, D11..8, D7..4, D3..0)."""
        v = self.firmware_raw
        text = f"{v >> 12 & 0xF}.{v >> 8 & 0xF}.{v >> 4 & 0xF}"
        return f"{text}-rc{v & 0xF}" if v & 0xF else text


@dataclass(frozen=True, slots=True)
class Limits:
    """53h Get System Limits."""

    stroke: float
    """mm"""
    min_speed: float
    """mm/s"""
    max_speed: float
    """mm/s"""
    min_acceleration: float
    """mm/s²"""
    max_acceleration: float
    """mm/s²"""
    min_force: float
    """N"""
    nominal_force: float
    """N"""
    overdrive_force: float
    """N"""


@dataclass(frozen=True, slots=True)
class Statistics:
    """42h Get Gripping Statistics."""

    total: int
    no_part: int
    lost_part: int


@dataclass(frozen=True, slots=True)
class SoftLimits:
    """35h Get Soft Limits, mm."""

    minus: float
    plus: float


@dataclass(frozen=True, slots=True)
class FingerInfo:
    """60h/70h Get Finger Info."""

    type: FingerType | int
    data_size: int
    """bytes in one frame of Get Finger Data (0: none)"""


@dataclass(frozen=True, slots=True)
class Sample:
    """One auto-update packet: ``value`` is SystemFlag (40h), GripperState (41h) or a float
    (43h width mm, 44h speed mm/s, 45h force N). ``time`` is ``time.monotonic()`` at receipt."""

    command: Command
    value: SystemFlag | GripperState | float | int
    time: float


@dataclass(frozen=True, slots=True)
class Reply:
    """A raw reply (``request()``): the status and the parameter bytes after it."""

    command_id: int
    status: Status | int
    params: bytes


__all__ = ["FingerFlag", "FingerInfo", "Limits", "Reply", "Sample", "SoftLimits", "State", "Statistics",
           "SystemInfo"]
