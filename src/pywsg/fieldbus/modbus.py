"""Modbus/TCP server for the fieldbus interface: the only module importing pymodbus server APIs.

pymodbus is pinned to 3.16.x (its datastore API changes between minor releases). In 3.16 the
supported hook is ``pymodbus.simulator.SimDevice(id=0, simdata=..., action=callback)``; the action
runs before a write is stored and may return an exception code. We keep four separate blocks:

=====================  ==========  ===============================================
table                  addresses   content
=====================  ==========  ===============================================
holding registers      0..3        output image (register k = byte 2k << 8 | 2k+1)
input registers        0..5        input image
coils                  0..15       CMDFLAGS bits 0..7, then IF1..IF8
discrete inputs        0..47       GSTATE bits, OF1..OF8, SYSSTATE bits 0..31
=====================  ==========  ===============================================

The controller is the single source of truth: every read refreshes the block from it (so SYSSTATE,
WIDTH and FORCE are fresh on every read) and every write is turned into a new output image before
pymodbus stores it. Anything outside these addresses is ILLEGAL DATA ADDRESS (02); function codes
pymodbus does not serve are ILLEGAL FUNCTION (01); writes to read-only tables are impossible by
function code (there is no "write input register"). Unit id: any (``id=0``).
"""

from __future__ import annotations

import asyncio
import logging
import struct
from dataclasses import dataclass, field
from typing import Any

from pymodbus.constants import ExcCodes
from pymodbus.server import ModbusTcpServer
from pymodbus.simulator import DataType, SimData, SimDevice

from .controller import FieldbusController
from .image import COILS, DISCRETE_INPUTS, INPUT_REGISTERS, OUTPUT_REGISTERS, InputImage, OutputImage, int_of

log = logging.getLogger(__name__)

STANDARD_PORT = 502

_FC_READ_COILS, _FC_READ_DI, _FC_READ_HR, _FC_READ_IR = 1, 2, 3, 4
_FC_WRITE_COIL, _FC_WRITE_REG, _FC_WRITE_COILS, _FC_WRITE_REGS = 5, 6, 15, 16
_FC_MASK_WRITE, _FC_READ_WRITE = 22, 23
_COIL_FCS = {_FC_READ_COILS, _FC_WRITE_COIL, _FC_WRITE_COILS}
_HR_FCS = {_FC_READ_HR, _FC_WRITE_REG, _FC_WRITE_REGS, _FC_MASK_WRITE, _FC_READ_WRITE}


_QUANTITY_LIMITS = {1: 2000, 2: 2000, 3: 125, 4: 125, 15: 1968, 16: 123}


# read coils / discrete inputs / holding / input registers, write single / multiple coils and
# registers, read/write multiple registers: what the WSG register map is served through
_SERVED_FCS = frozenset({0x01, 0x02, 0x03, 0x04, 0x05, 0x06, 0x0F, 0x10, 0x17})
_UNDECODABLE_FC = 0x7F


def _bad_quantity(pdu: bytes) -> bool:
    """True if a read/write-multiple request's quantity is outside the Modbus limits."""
    limit = _QUANTITY_LIMITS.get(pdu[0]) if pdu else None
    if limit is None or len(pdu) < 5:
        return False
    count = pdu[3] << 8 | pdu[4]
    return not 1 <= count <= limit


def _words(bits: list[bool]) -> list[int]:
    """Bits packed 16 per register, bit 0 first (pymodbus' bit-block layout)."""
    return [int_of(bits[i:i + 16]) for i in range(0, len(bits), 16)]


class FieldbusModbusAdapter:
    """Maps pymodbus' SimDevice action onto a :class:`FieldbusController`."""

    def __init__(self, controller: FieldbusController) -> None:
        self.controller = controller
        self.requests = 0
        self._last_fc: dict[int, tuple[int, bool]] = {}

    def device(self) -> SimDevice:
        """The pymodbus device: four separate blocks, bit-addressed coils and discrete inputs."""
        simdata = (
            [SimData(0, count=COILS, values=False, datatype=DataType.BITS)],
            [SimData(0, count=DISCRETE_INPUTS, values=False, datatype=DataType.BITS)],
            [SimData(0, count=OUTPUT_REGISTERS, values=0, datatype=DataType.REGISTERS)],
            [SimData(0, count=INPUT_REGISTERS, values=0, datatype=DataType.REGISTERS)],
        )
        return SimDevice(id=0, simdata=simdata, action=self.action)

    async def action(self, function_code: int, start_address: int, address: int, count: int,
                     registers: list[int], set_values: list[int] | list[bool] | None) -> ExcCodes | None:
        """pymodbus hook: called with the block's registers (modify in place) before a write is stored."""
        self.requests += 1
        ctl = self.controller
        try:
            if set_values is not None and function_code in _COIL_FCS:
                bits = [bool(v) for v in set_values]
                ctl.write_outputs(ctl.output_image.with_coils(address, bits))
            elif set_values is not None and function_code in _HR_FCS:
                regs = ctl.output_image.registers()
                offset = address - start_address
                regs[offset:offset + len(set_values)] = [int(v) & 0xFFFF for v in set_values]
                ctl.write_outputs(OutputImage.from_registers(regs))
        except (ValueError, IndexError):
            return ExcCodes.ILLEGAL_VALUE
        except Exception:  # never let a device error kill the bus: report it as a device failure
            log.exception("fieldbus write failed")
            return ExcCodes.DEVICE_FAILURE
        self._refresh(function_code, registers)
        return None

    def trace_packet(self, sending: bool, data: bytes) -> bytes:
        """pymodbus packet hook: make undecodable requests get the exception a PLC expects.

        pymodbus 3.16 answers every request it cannot decode with function code 80h and exception
        01: a Modbus master expects the request's function code | 80h, and exception 03 (ILLEGAL
        DATA VALUE) when only the quantity is out of range (e.g. reading 0 registers).
        """
        if not sending:
            pos = 0
            out = bytearray(data)
            while pos + 8 <= len(data):   # MBAP: tid, protocol, length (unit id + PDU), unit id, FC
                tid, _, length = struct.unpack_from(">HHH", data, pos)
                pdu = data[pos + 7:pos + 6 + max(length, 2)]
                self._last_fc[tid] = (pdu[0], _bad_quantity(pdu))
                if pdu[0] not in _SERVED_FCS:
                    # a code pymodbus would serve (diagnostics, event counters, ...) but the WSG's
                    # register map has no use for: make it undecodable so it is ILLEGAL FUNCTION
                    out[pos + 7] = _UNDECODABLE_FC
                for k in list(self._last_fc)[:-64]:
                    del self._last_fc[k]
                pos += 6 + max(length, 2)
            return bytes(out)
        if len(data) >= 9 and data[7] & 0x80 and data[8] == ExcCodes.ILLEGAL_FUNCTION:
            tid = struct.unpack_from(">H", data)[0]
            fc, bad_quantity = self._last_fc.pop(tid, (data[7] & 0x7F, False))
            code = ExcCodes.ILLEGAL_VALUE if bad_quantity else ExcCodes.ILLEGAL_FUNCTION
            return data[:7] + bytes([(fc & 0x7F) | 0x80, code]) + data[9:]
        return data

    def _refresh(self, function_code: int, registers: list[int]) -> None:
        """Fill the accessed block from the controller (reads see fresh values)."""
        ctl = self.controller
        if function_code in _COIL_FCS:
            fresh = _words(ctl.output_image.coils())
        elif function_code in _HR_FCS:
            fresh = ctl.output_image.registers()
        elif function_code == _FC_READ_DI:
            fresh = _words(ctl.input_image().discrete_inputs())
        elif function_code == _FC_READ_IR:
            fresh = ctl.input_image().registers()
        else:
            return
        registers[:len(fresh)] = fresh


@dataclass
class ModbusHandle:
    """A running Modbus/TCP fieldbus server. ``port`` is the bound port (useful with port 0)."""

    host: str
    port: int
    controller: FieldbusController
    server: Any = field(repr=False)
    adapter: FieldbusModbusAdapter = field(repr=False)

    @property
    def output_image(self) -> OutputImage:
        """The output image last written by the PLC."""
        return self.controller.output_image

    def input_image(self) -> InputImage:
        """The input image now."""
        return self.controller.input_image()

    async def close(self) -> None:
        """Stop serving and close the controller's device session."""
        await self.server.shutdown()
        self.controller.close()
        await asyncio.sleep(0)


async def serve_modbus(gripper: Any, host: str = "0.0.0.0", port: int = STANDARD_PORT,
                       controller: FieldbusController | None = None) -> ModbusHandle:
    """Serve ``gripper``'s fieldbus interface over Modbus/TCP on ``host:port`` (port 0: any free port).

    Runs on the current event loop; the gripper must be polled by a runner (e.g.
    ``pywsg.server.DeviceRunner``) so motions finish. Raises OSError if the port cannot be bound.
    """
    ctl = controller or FieldbusController(gripper)
    adapter = FieldbusModbusAdapter(ctl)
    server = ModbusTcpServer(adapter.device(), address=(host, port), trace_packet=adapter.trace_packet)
    # Bind ourselves first so a busy port raises OSError (pymodbus only logs and returns False).
    if not await server.listen():
        ctl.close()
        raise OSError(f"cannot listen for Modbus/TCP on {host}:{port}")
    sockets = getattr(server.transport, "sockets", None) or []
    bound = sockets[0].getsockname()[1] if sockets else port
    log.info("Modbus/TCP fieldbus on %s:%d", host, bound)
    return ModbusHandle(host, bound, ctl, server, adapter)
