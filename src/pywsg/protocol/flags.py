"""Flags and enumerations of the command manual (Appendix B, C; 3.5.1; 3.6) and the fieldbus."""

from __future__ import annotations

from enum import IntEnum, IntFlag

__all__ = ["AutoUpdateFlag", "DeviceType", "FingerFlag", "FingerType", "GState", "GripperState", "HomingDirection",
           "NamedFlag", "PrepositionFlag", "SystemFlag"]


class NamedFlag(IntFlag):
    """An IntFlag that prints its flag names: ``SF_REFERENCED|SF_CMD_FAILURE``, not ``262145``.

    Python 3.11 prints IntFlag members as plain numbers; people reading ``print(flags)`` want names.
    Format specs still work on the number (``f"{flags:#x}"`` gives ``0x40001``).
    """

    def __str__(self) -> str:
        value = int(self)
        names = [m.name for m in type(self) if m.name and m.value and m.value & (m.value - 1) == 0
                 and value & m.value]
        rest = value & ~sum(int(m.value) for m in type(self) if m.value and m.value & (m.value - 1) == 0)
        if rest:
            names.append(hex(rest))
        if names:
            return "|".join(names)
        zero = next((n for n, m in type(self).__members__.items() if m.value == 0), None)
        return zero or "0"

    def __format__(self, spec: str) -> str:
        return str(self) if not spec else int.__format__(int(self), spec)


class SystemFlag(NamedFlag):
    """System state flags, 32 bits (Appendix B). Read with 40h Get System State."""

    NONE = 0
    SF_REFERENCED = 1 << 0
    SF_MOVING = 1 << 1
    SF_BLOCKED_MINUS = 1 << 2
    SF_BLOCKED_PLUS = 1 << 3
    SF_SOFT_LIMIT_MINUS = 1 << 4
    SF_SOFT_LIMIT_PLUS = 1 << 5
    SF_AXIS_STOPPED = 1 << 6
    SF_TARGET_POS_REACHED = 1 << 7
    SF_OVERDRIVE_MODE = 1 << 8
    SF_FORCECNTL_MODE = 1 << 9
    SF_FAST_STOP = 1 << 12
    SF_TEMP_WARNING = 1 << 13
    SF_TEMP_FAULT = 1 << 14
    SF_POWER_FAULT = 1 << 15
    SF_CURR_FAULT = 1 << 16
    SF_FINGER_FAULT = 1 << 17
    SF_CMD_FAILURE = 1 << 18
    SF_SCRIPT_RUNNING = 1 << 19
    SF_SCRIPT_FAILURE = 1 << 20

    def names(self) -> list[str]:
        """Names of the set flags, lowest bit first."""
        return [f.name for f in SystemFlag if f.value and f.name and self & f]


class GripperState(IntEnum):
    """Grasping state (41h, Appendix C)."""

    IDLE = 0
    GRIPPING = 1
    NO_PART = 2
    PART_LOST = 3
    HOLDING = 4
    RELEASING = 5
    POSITIONING = 6
    ERROR = 7


class GState(NamedFlag):
    """Fieldbus GSTATE byte: the gripper state as one-hot bits (fieldbus manual, input byte 0)."""

    IDLE = 1 << 0
    GRIPPING = 1 << 1
    NO_PART = 1 << 2
    PART_LOST = 1 << 3
    HOLDING = 1 << 4
    RELEASING = 1 << 5
    POSITIONING = 1 << 6
    ERROR = 1 << 7

    @classmethod
    def from_state(cls, state: GripperState) -> GState:
        return cls(1 << int(state))


class HomingDirection(IntEnum):
    """20h Homing DIRECTION parameter."""

    DEFAULT = 0
    POSITIVE = 1
    NEGATIVE = 2


class DeviceType(IntEnum):
    """50h Get System Information TYPE."""

    UNKNOWN = 0
    WSG50 = 1
    WSG32 = 2
    KMS40 = 3
    WTS = 4
    WSG25 = 5
    WSG70 = 6


class FingerType(IntEnum):
    """60h/70h finger TYPE."""

    GENERIC = 0
    WSG_FMF = 1
    WSG_DSA = 2


class FingerFlag(NamedFlag):
    """61h/71h finger flags (16 bits)."""

    NONE = 0
    POWER_ON = 1 << 0
    CONFIG_AVAIL = 1 << 1
    COMM_OPEN = 1 << 2
    POWER_FAULT = 1 << 8
    COMM_FAULT = 1 << 9


class PrepositionFlag(NamedFlag):
    """21h Pre-position FLAGS byte."""

    ABSOLUTE = 0
    RELATIVE = 1 << 0
    STOP_ON_BLOCK = 1 << 1


class AutoUpdateFlag(NamedFlag):
    """FLAGS byte of 40h, 41h, 43h, 44h, 45h."""

    NONE = 0
    AUTO_UPDATE = 1 << 0
    CHANGE_ONLY = 1 << 1
