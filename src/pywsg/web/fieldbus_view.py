"""Diagnosis → Fieldbus Monitor: the I/O register view of the fieldbus manual (003 §6, figure 1).

Each register image is shown byte by byte (index, hex) with the register it belongs to, decoded:
flag bytes as named check boxes, numbers in mm, mm/s, N, the status code by name. Bytes come from
the ``FieldbusController`` and are decoded by ``pywsg.fieldbus.image`` (the one place that knows the
layout and byte order: docs/architecture.md, "Modbus register byte order"). The Bus State box lists
every bus adapter attached to the controller with the rows its ``bus_state()`` gives, so a bus only
implements that (``pywsg.fieldbus.bus.BusAdapter``).
"""

from __future__ import annotations

import logging
import time
from typing import Any

from ..fieldbus.image import INPUT_SIZE, OUTPUT_SIZE, InputImage, OutputImage
from ..protocol import GState, Status, SystemFlag

log = logging.getLogger(__name__)

# Bit labels as in the screenshot (STOP/ACK, JOG+, ...), lowest bit first.
CMD_BITS = ("MOVE", "GRIP", "RELEASE", "HOMING", "STOP/ACK", "FASTSTOP", "JOG+", "JOG-")
GSTATE_BITS = tuple(str(m.name) for m in GState)


def _flags(offset: int, name: str, value: int, labels: tuple[str, ...]) -> dict[str, Any]:
    on = [bool(value >> i & 1) for i in range(len(labels))]
    bits = [{"name": b, "on": o} for b, o in zip(labels, on, strict=True)]
    return {"offset": offset, "size": 1, "name": name, "kind": "flags", "raw": value, "bits": bits,
            "text": " ".join(b for b, o in zip(labels, on, strict=True) if o) or "-"}


def _number(offset: int, name: str, raw: int, value: float, unit: str) -> dict[str, Any]:
    return {"offset": offset, "size": 2, "name": name, "kind": "number", "raw": raw, "value": value,
            "unit": unit, "text": f"{value:.2f} {unit}"}


def output_registers(image: OutputImage, model: str) -> list[dict[str, Any]]:
    """Output image (PLC → WSG), decoded: manual 003 §4.1.1."""
    return [
        _flags(0, "Command Flags", int(image.cmdflags), CMD_BITS),
        _flags(1, "User Flags", image.if_flags, tuple(f"IF{i}" for i in range(1, 9))),
        _number(2, "Width", image.width, image.width_mm, "mm"),
        _number(4, "Speed", image.speed, image.speed_mm_s, "mm/s"),
        _number(6, "Force Limit", image.force_limit, image.force_n(model), "N"),
    ]


def input_registers(image: InputImage, model: str) -> list[dict[str, Any]]:
    """Input image (WSG → PLC), decoded: manual 003 §4.1.2."""
    sysstate = int(image.sysstate)
    status = image.status_code
    return [
        _flags(0, "Gripping State", int(image.gstate), GSTATE_BITS),
        _flags(1, "User Flags", image.of_flags, tuple(f"OF{i}" for i in range(1, 9))),
        {"offset": 2, "size": 4, "name": "System State", "kind": "sysstate", "raw": sysstate,
         "text": f"{sysstate:08X}h", "flags": SystemFlag(sysstate).names()},
        _number(6, "Current Opening Width", image.width, image.width_mm, "mm"),
        _number(8, "Gripping Force", image.force, image.force_n(model), "N"),
        {"offset": 10, "size": 2, "name": "Error Code", "kind": "status", "raw": image.status,
         "text": status.name if isinstance(status, Status) else f"unknown ({status})"},
    ]


def _bytes_view(data: bytes, registers: list[dict[str, Any]]) -> dict[str, Any]:
    return {
        "available": True,
        "hex": data.hex(" ").upper(),
        "bytes": [{"index": i, "hex": f"{b:02X}h"} for i, b in enumerate(data)],
        "registers": registers,
    }


_MISSING: dict[str, Any] = {"available": False, "hex": "", "bytes": [], "registers": []}


def controller_of(fieldbus: Any) -> Any:
    """A FieldbusController, given one or a ``serve_modbus`` handle (``.controller``)."""
    return getattr(fieldbus, "controller", fieldbus)


def _buses(fieldbus: Any) -> list[Any]:
    """The bus adapters feeding the controller (a lone ``serve_modbus`` handle is its own bus)."""
    buses = list(getattr(controller_of(fieldbus), "buses", ()) or ())
    if not buses and hasattr(fieldbus, "bus_state"):
        buses = [fieldbus]
    return buses


def buses_view(fieldbus: Any) -> list[dict[str, Any]]:
    """The Bus State box (003 §6): one entry per attached bus, ``{"name", "rows": [{"label", "text"}]}``,
    the rows in the order the bus's ``bus_state()`` gives them. A bus whose ``bus_state()`` fails shows
    one row saying so (the monitor keeps running)."""
    out = []
    for bus in _buses(fieldbus):
        name = str(getattr(bus, "name", type(bus).__name__))
        try:
            rows = [{"label": str(k), "text": str(v)} for k, v in bus.bus_state().items()]
        except Exception as exc:  # one broken bus must not take the monitor down
            log.exception("%s: bus_state() failed", name)
            rows = [{"label": "Interface state", "text": f"unknown ({type(exc).__name__})"}]
        out.append({"name": name, "rows": rows})
    return out


def bus_state(fieldbus: Any) -> dict[str, Any]:
    """The Modbus/TCP server's state in numbers (for scripts; the page shows :func:`buses_view`).

    ``state``: "online" (a master is connected), "waiting" (served, no master), "offline" (no
    Modbus/TCP server serves this controller). ``last_write`` and ``now`` are ``time.time()`` seconds.
    """
    handle = next((b for b in _buses(fieldbus) if hasattr(b, "masters")), None)
    if handle is None:
        return {"protocol": "Modbus/TCP", "state": "offline", "port": None, "masters": 0, "last_write": None,
                "now": time.time()}
    masters = int(handle.masters)
    return {"protocol": "Modbus/TCP", "state": "online" if masters else "waiting", "port": handle.port,
            "masters": masters, "last_write": handle.last_write, "now": time.time()}


def fieldbus_view(fieldbus: Any) -> dict[str, Any]:
    """What the Fieldbus Monitor page and its WebSocket messages carry."""
    ctl = controller_of(fieldbus)
    if ctl is None:
        return {"available": False, "model": None, "output": _MISSING, "input": _MISSING, "bus": bus_state(None),
                "buses": []}
    model = str(getattr(ctl, "model", "wsg50"))
    out = bytes(ctl.output_bytes)[:OUTPUT_SIZE]
    inp = bytes(ctl.input_bytes())[:INPUT_SIZE]
    return {
        "available": True,
        "model": model,
        "status": int(getattr(ctl, "status", 0)),
        "output": _bytes_view(out, output_registers(OutputImage.unpack(out), model)),
        "input": _bytes_view(inp, input_registers(InputImage.unpack(inp), model)),
        "bus": bus_state(fieldbus),
        "buses": buses_view(fieldbus),
    }
