"""The driver: :class:`AsyncGripper` (asyncio) and :class:`Gripper` (blocking), over TCP, UDP and serial."""

from __future__ import annotations

from ._async.gripper import AsyncFinger, AsyncGripper, AsyncMotion, AsyncStream, ReconnectPolicy
from ._sync.connect import open_sync as open_transport
from ._sync.gripper import Finger, Gripper, Motion, Stream
from ._sync.transport import SyncTransport
from .commlog import CommEntry, describe
from .types import FingerInfo, Limits, Reply, Sample, SoftLimits, State, Statistics, SystemInfo
from .url import Endpoint, parse_url

__all__ = [
    "AsyncFinger", "AsyncGripper", "AsyncMotion", "AsyncStream", "CommEntry", "Endpoint", "Finger", "FingerInfo",
    "Gripper", "Limits", "Motion", "ReconnectPolicy", "Reply", "Sample", "SoftLimits", "State", "Statistics",
    "Stream", "SyncTransport", "SystemInfo", "describe", "open_transport", "parse_url",
]
