"""Asyncio transports serving virtual grippers: TCP, UDP, serial (pty or device), CAN (inferred).

:class:`SimServer` starts grippers with their interfaces (what ``wsg sim`` runs); see docs/sim.md.
"""

from __future__ import annotations

from .can_bus import CanServer
from .limits import DEFAULT_LIMITS, Limits
from .scheduler import DeviceRunner, Scheduler, get_scheduler
from .serial_port import SerialServer
from .sim import SimError, SimGripper, SimOptions, SimServer, run_sim
from .tcp import TcpServer
from .udp import UdpServer

__all__ = [
    "DEFAULT_LIMITS", "CanServer", "DeviceRunner", "Limits", "Scheduler", "SerialServer", "SimError",
    "SimGripper", "SimOptions", "SimServer", "TcpServer", "UdpServer", "get_scheduler", "run_sim",
]
