"""Fieldbus interface of the WSG (fieldbus manuals 002/003): register image, controller, Modbus/TCP, PLC side.

- :mod:`.image` — the 8-byte output / 12-byte input register image (sans-IO, bus units).
- :mod:`.controller` — :class:`FieldbusController`: edges, jog levels, FAST STOP rules on a virtual gripper.
- :mod:`.modbus` — ``serve_modbus(gripper, host, port)``: the image over Modbus/TCP (pymodbus 3.13.1 … 3.16).
- :mod:`.plc` — :class:`FieldbusGripper`: the PLC side, a Modbus/TCP master with the same edge semantics.
- :mod:`.profibus` — PROFIBUS DP-V0 slave (FDL, DP state machine, serial line), GSD facts, diagnosis message.
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
