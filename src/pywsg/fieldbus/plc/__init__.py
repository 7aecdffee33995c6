"""The PLC side of the fieldbus interface: a master over any bus, and the manual's gripping cycle.

- :class:`AsyncFieldbusGripper` (asyncio, ``async_gripper.py``) and :class:`FieldbusGripper` (blocking,
  ``gripper.py``) drive a real WSG
  or ``wsg sim`` over any :class:`~pywsg.fieldbus.exchange.ImageExchange` (Modbus/TCP, PROFINET,
  PROFIBUS; ``open_url("modbus-tcp://HOST:PORT")`` picks it by URL) with the bus's edge semantics:
  set the parameters, raise the command flag, wait until the gripper shows the command started,
  drop the flag, wait for the result. Units: mm, mm/s, N.
- :class:`GrippingCycle` (``cycle.py``) is the SCL demo of 002 Appendix D (states −1..10) ported to Python as a
  sans-IO scan function: ``step(inputs, now) -> outputs``; ``wsg plc-demo`` runs it over any bus.
  It reads the input bytes through :class:`WsgReceive`, the listing's ``WSG_RECEIVE`` struct mapped
  as an S7 PLC maps it (``receive.STW1.IDLE``, ``receive.SYSSTATE.REFERENCED``).
"""

from __future__ import annotations

from ..exchange import FieldbusConnectionError
from .async_gripper import AsyncFieldbusGripper, FieldbusError
from .cycle import GSTATE_NAMES, STEP_TEXT, STW1_BOOLS, SYSSTATE_BOOLS, CycleConfig, GrippingCycle, SclBools, WsgReceive
from .gripper import FieldbusGripper

__all__ = [
    "GSTATE_NAMES",
    "STEP_TEXT",
    "STW1_BOOLS",
    "SYSSTATE_BOOLS",
    "AsyncFieldbusGripper",
    "CycleConfig",
    "FieldbusConnectionError",
    "FieldbusError",
    "FieldbusGripper",
    "GrippingCycle",
    "SclBools",
    "WsgReceive",
]
