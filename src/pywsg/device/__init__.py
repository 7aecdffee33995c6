"""The virtual gripper (sans-IO): a WSG that answers every command of the command manual.

See docs/device.md. Public names::

    VirtualGripper, ManualClock, Settings, SettingsError, Session, Snapshot, Profile, PROFILES,
    SystemLog, LogEntry, FirmwarePlugin, PLUGINS
"""

from .clock import Clock, ManualClock, ScaledClock, monotonic_clock
from .faults import Faults, Obstacle
from .fingers import Finger
from .gripper import Snapshot, VirtualGripper
from .log import LogEntry, LogLevel, SystemLog
from .plugins import PLUGINS, FirmwarePlugin
from .profiles import DEFAULT_MODEL, PROFILES, Profile, decode_fw_version, encode_fw_version, get_profile
from .session import Session, Subscription
from .settings import Settings, SettingsError

__all__ = [
    "DEFAULT_MODEL", "PLUGINS", "PROFILES", "Clock", "Faults", "Finger", "FirmwarePlugin", "LogEntry",
    "LogLevel", "ManualClock", "Obstacle", "Profile", "ScaledClock", "Session", "Settings", "SettingsError",
    "Snapshot", "Subscription", "SystemLog", "VirtualGripper", "decode_fw_version", "encode_fw_version",
    "get_profile", "monotonic_clock",
]
