"""Fieldbus interface of the WSG (fieldbus manuals 002/003): one controller, many buses.

- :mod:`.image` — the 8-byte output / 12-byte input register image (sans-IO, bus units).
- :mod:`.controller` — :class:`FieldbusController`: edges, jog levels, FAST STOP rules on a virtual
  gripper; every bus of the gripper feeds this one controller (``attach_bus``, ``fail_safe``).
- :mod:`.bus` — :class:`~.bus.BusAdapter`, what a bus on the gripper's side implements.
- :mod:`.exchange` — :class:`~.exchange.ImageExchange`, what a master on the PLC's side implements,
  and ``open_exchange(url)``.
- :mod:`.plc` — :class:`FieldbusGripper`, :class:`~.plc.GrippingCycle`: the PLC side over any bus.
- one subpackage per bus, both sides: :mod:`.modbus` (Modbus/TCP), :mod:`.profibus` (PROFIBUS DP-V0
  slave: FDL, DP state machine, serial line, GSD facts, diagnosis message), ``profinet`` (PROFINET IO).
"""

from __future__ import annotations

from typing import Any

from .image import CmdFlag, InputImage, OutputImage, force_scale

__all__ = ["CmdFlag", "FieldbusController", "FieldbusGripper", "InputImage", "OutputImage", "force_scale"]


def __getattr__(name: str) -> Any:
    # Imported lazily: the controller needs the protocol catalog, the PLC side needs the pymodbus client.
    if name == "FieldbusController":
        from .controller import FieldbusController
        return FieldbusController
    if name == "FieldbusGripper":
        from .plc import FieldbusGripper
        return FieldbusGripper
    raise AttributeError(name)
