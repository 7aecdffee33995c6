"""Firmware plugins: custom command IDs handled in Python, as on-board scripts do on a real WSG.

A real gripper runs Lua scripts that register command IDs (B0h and up) for high-rate control;
the virtual gripper runs :class:`FirmwarePlugin` objects instead. Shipped:

- ``ros_measure``: the public WSG ROS driver's ``cmd_measure.lua`` (B0h measure, B1h position,
  B2h speed).
- ``umi_measure``: the Stanford UMI driver's ``cmd_measure.lua`` (B0h measure, B1h position PD).
- ``if_of_mirror``: copies the fieldbus IF user flags to OF (a minimal script for PLC tests).

Commands of a plugin that is not loaded answer E_CMD_UNKNOWN; SF_SCRIPT_RUNNING is set while
any plugin runs.
"""

from __future__ import annotations

from .base import FirmwarePlugin, MirrorPlugin, ScriptHost
from .ros_measure import RosMeasurePlugin
from .umi_measure import UmiMeasurePlugin

PLUGINS: dict[str, type[FirmwarePlugin]] = {
    RosMeasurePlugin.name: RosMeasurePlugin,
    UmiMeasurePlugin.name: UmiMeasurePlugin,
    MirrorPlugin.name: MirrorPlugin,
}

__all__ = ["PLUGINS", "FirmwarePlugin", "MirrorPlugin", "RosMeasurePlugin", "ScriptHost", "UmiMeasurePlugin"]
