"""pywsg: driver, virtual gripper, fieldbus interface and tools for WSG grippers."""

from __future__ import annotations

__version__ = "0.1.0"
