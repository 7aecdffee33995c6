"""The fieldbus register map as data: every Modbus/TCP address of the WSG image (003 §4, 002 §3).

Generated from the definitions the server itself uses (:mod:`pywsg.fieldbus.image` for sizes and
bit order, :mod:`.fieldbus_view` for the register names the Fieldbus Monitor shows), so the
download cannot disagree with what the bus serves. Rows: table, address, image bytes/bit, name,
type, unit, access. Help → Documentation offers it as CSV and JSON.
"""

from __future__ import annotations

import csv
import io
from typing import Any

from ..fieldbus.image import INPUT_REGISTERS, OUTPUT_REGISTERS, InputImage, OutputImage
from ..protocol import SystemFlag
from .fieldbus_view import CMD_BITS, GSTATE_BITS, input_registers, output_registers

COLUMNS = ("table", "address", "image", "bytes", "bit", "name", "type", "unit", "access", "description")

# bus units of the numeric fields (002 §3.1/§3.2); FORCE/FORCELIMIT are 1/10 N on the WSG 70
_NUMBERS: dict[str, tuple[str, str]] = {
    "Width": ("int16", "0.01 mm"), "Speed": ("uint16", "0.01 mm/s"),
    "Force Limit": ("int16", "0.01 N (WSG 70: 0.1 N)"), "Current Opening Width": ("int16", "0.01 mm"),
    "Gripping Force": ("int16", "0.01 N (WSG 70: 0.1 N)"), "Error Code": ("uint16", "status code"),
}


def _byte_names(registers: list[dict[str, Any]], size: int) -> list[str]:
    names = [""] * size
    for reg in registers:
        for i in range(reg["offset"], reg["offset"] + reg["size"]):
            names[i] = reg["name"]
    return names


def _register_rows(table: str, image: str, count: int, names: list[str], access: str) -> list[dict[str, Any]]:
    rows = []
    for k in range(count):
        parts = list(dict.fromkeys(names[2 * k:2 * k + 2]))  # one name, or two byte-wide fields
        name = " | ".join(parts)
        typ, unit = _NUMBERS.get(name, ("2 × uint8" if len(parts) == 2 else "bits", ""))
        rows.append({"table": table, "address": k, "image": image, "bytes": f"{2 * k}..{2 * k + 1}", "bit": "",
                     "name": name, "type": typ, "unit": unit, "access": access,
                     "description": f"byte {2 * k} << 8 | byte {2 * k + 1}"})
    return rows


def _bit_rows(table: str, image: str, labels: list[str], access: str) -> list[dict[str, Any]]:
    return [{"table": table, "address": i, "image": image, "bytes": str(i // 8), "bit": str(i % 8), "name": label,
             "type": "bit", "unit": "", "access": access, "description": f"image byte {i // 8}, bit {i % 8}"}
            for i, label in enumerate(labels)]


def register_map() -> list[dict[str, Any]]:
    """Every address of the four Modbus tables, in table and address order."""
    out_names = _byte_names(output_registers(OutputImage(), "wsg50"), len(OutputImage().pack()))
    in_names = _byte_names(input_registers(InputImage(), "wsg50"), len(InputImage().pack()))
    coil_labels = list(CMD_BITS) + [f"IF{i}" for i in range(1, 9)]
    sys_labels = [SystemFlag(1 << n).name or f"bit {n} (reserved)" for n in range(32)]
    di_labels = list(GSTATE_BITS) + [f"OF{i}" for i in range(1, 9)] + [f"SYSSTATE {s}" for s in sys_labels]
    return (_register_rows("holding register", "output", OUTPUT_REGISTERS, out_names, "read/write")
            + _register_rows("input register", "input", INPUT_REGISTERS, in_names, "read")
            + _bit_rows("coil", "output", coil_labels, "read/write")
            + _bit_rows("discrete input", "input", di_labels, "read"))


def register_map_csv() -> str:
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=COLUMNS, lineterminator="\n")
    w.writeheader()
    w.writerows(register_map())
    return buf.getvalue()
