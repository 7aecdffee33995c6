"""pywsg: driver, virtual gripper, fieldbus interface and tools for WSG grippers."""

from __future__ import annotations

__version__ = "0.4.0"

from .client import (
    AsyncGripper,
    AsyncMotion,
    AsyncStream,
    CommEntry,
    Gripper,
    Motion,
    ReconnectPolicy,
    Sample,
    State,
    Stream,
)
from .errors import (
    AbortedError,
    AccessDeniedError,
    AxisBlockedError,
    ChecksumError,
    CommandFailedError,
    CommandUnknownError,
    ConnectionLostError,
    FastStopError,
    NoPartError,
    NotReferencedError,
    RangeError,
    TimeoutError,
    WsgError,
)
from .protocol import Command, GripperState, Status, SystemFlag

__all__ = [
    "AbortedError", "AccessDeniedError", "AsyncGripper", "AsyncMotion", "AsyncStream", "AxisBlockedError",
    "ChecksumError", "CommEntry", "Command", "CommandFailedError", "CommandUnknownError", "ConnectionLostError",
    "FastStopError", "Gripper", "GripperState", "Motion", "NoPartError", "NotReferencedError", "RangeError",
    "ReconnectPolicy", "Sample", "State", "Status", "Stream", "SystemFlag", "TimeoutError", "WsgError",
    "__version__",
]
