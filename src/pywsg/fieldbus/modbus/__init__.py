"""Modbus/TCP, both sides: the gripper's server (:mod:`.server`, ``serve_modbus``) and the PLC's
master (:mod:`.exchange`, ``modbus-tcp://HOST[:PORT]``).

Imported lazily: only :mod:`.server` imports pymodbus' server API, only :mod:`.exchange` its client.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from .exchange import ModbusExchange
    from .server import STANDARD_PORT, ModbusHandle, check_pdu, serve_modbus

__all__ = ["STANDARD_PORT", "ModbusExchange", "ModbusHandle", "check_pdu", "serve_modbus"]

_HOME = {"ModbusHandle": "server", "check_pdu": "server", "serve_modbus": "server", "STANDARD_PORT": "server",
         "ModbusExchange": "exchange"}


def __getattr__(name: str) -> Any:
    if name in _HOME:
        import importlib

        return getattr(importlib.import_module(f"{__name__}.{_HOME[name]}"), name)
    raise AttributeError(name)
