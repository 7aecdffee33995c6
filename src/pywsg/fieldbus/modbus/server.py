"""Modbus/TCP server for the fieldbus interface: the only module importing pymodbus server APIs.

pymodbus ``>=3.13.1,<3.17`` (its server API changes between minor releases: 3.13.0 and older lack
what is used here, 3.17 does not exist yet; 3.13.1, 3.14.0, 3.15.0 and 3.16.1 pass tests/fieldbus).
The hook is ``pymodbus.simulator.SimDevice(id=0, simdata=..., action=callback)``; the action runs
before a write is stored and may return an exception code. We keep four separate blocks:

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
the map does not use are ILLEGAL FUNCTION (01); malformed quantities and values are ILLEGAL DATA
VALUE (03, :func:`check_pdu`); writes to read-only tables are impossible by function code (there
is no "write input register"). Unit id: any (``id=0``).

The TCP stream is framed here, not by pymodbus 3.16, whose framing drops pipelined requests and
stalls on a foreign protocol id (:class:`_Connection`, docs/fieldbus.md "Conformance").
"""

from __future__ import annotations

import asyncio
import logging
import struct
import time
from collections import deque
from dataclasses import dataclass, field
from typing import Any

from pymodbus.constants import ExcCodes
from pymodbus.pdu import ExceptionResponse, ModbusPDU
from pymodbus.server import ModbusTcpServer
from pymodbus.server.requesthandler import ServerRequestHandler
from pymodbus.simulator import DataType, SimData, SimDevice

from ...server.conncap import cap_modbus_server
from ..controller import FieldbusController
from ..image import COILS, DISCRETE_INPUTS, INPUT_REGISTERS, OUTPUT_REGISTERS, InputImage, OutputImage, int_of

log = logging.getLogger(__name__)

STANDARD_PORT = 502  # Modbus/TCP's registered port


_FC_READ_COILS, _FC_READ_DI, _FC_READ_HR, _FC_READ_IR = 1, 2, 3, 4
_FC_WRITE_COIL, _FC_WRITE_REG, _FC_WRITE_COILS, _FC_WRITE_REGS = 5, 6, 15, 16
_FC_MASK_WRITE, _FC_READ_WRITE = 22, 23
_COIL_FCS = {_FC_READ_COILS, _FC_WRITE_COIL, _FC_WRITE_COILS}
_HR_FCS = {_FC_READ_HR, _FC_WRITE_REG, _FC_WRITE_REGS, _FC_MASK_WRITE, _FC_READ_WRITE}

# read coils / discrete inputs / holding / input registers, write single / multiple coils and
# registers, read/write multiple registers: what the WSG register map is served through
_SERVED_FCS = frozenset({0x01, 0x02, 0x03, 0x04, 0x05, 0x06, 0x0F, 0x10, 0x17})
#: Largest MBAP length field: unit id + a PDU of at most 253 bytes (an ADU is at most 260 bytes).
MAX_MBAP_LENGTH = 254
#: Requests queued on one connection before the server stops reading from it (back-pressure).
MAX_QUEUED = 64
#: pymodbus' receive buffer limit for our connections. pymodbus drops the whole buffer, silently,
#: when a read makes it longer than its default (the framer's 260 bytes), losing pipelined requests
#: (fuzz F1). We cut every complete ADU at once, so the buffer holds at most one partial ADU
#: (< 260 bytes) plus one read (asyncio reads at most 256 KiB): this limit is never reached.
RECV_BUFFER_LIMIT = 1 << 20
#: Seconds an ADU may take to arrive whole, from its first byte. A master sends a request in one TCP
#: segment (it is at most 260 bytes); a peer trickling one byte every few seconds kept a connection
#: slot forever, since the idle timeout only sees silence (32 such peers locked every PLC out).
ADU_DEADLINE = 2.0
#: One peer address may hold at most this share of the connection cap (but at least one): the rest
#: stay for other masters, so one host (a misbehaving HMI, a scanner) cannot lock every PLC out.
PEER_SHARE = 0.75


#: Size of the table each function code addresses (coils, discrete inputs, holding / input registers).
_TABLE_SIZE = {1: COILS, 5: COILS, 15: COILS, 2: DISCRETE_INPUTS, 3: OUTPUT_REGISTERS, 6: OUTPUT_REGISTERS,
               16: OUTPUT_REGISTERS, 23: OUTPUT_REGISTERS, 4: INPUT_REGISTERS}


def check_pdu(pdu: bytes) -> ExcCodes | None:
    """The exception a request PDU earns, or None if pymodbus may execute it.

    Modbus Application Protocol V1.1b3, in the spec's order: a function code the WSG map does not
    serve → 01 ILLEGAL FUNCTION; a quantity outside its range, a byte count that does not match it,
    a wrong PDU length or an FC5 value other than FF00h / 0000h → 03 ILLEGAL DATA VALUE; a range
    beyond the table (coils 0..15, discrete inputs 0..47, holding registers 0..3, input registers
    0..5) → 02 ILLEGAL DATA ADDRESS. Checked here so the answers do not depend on the pymodbus release.
    """
    code = _check_value(pdu)
    if code is not None:
        return code
    fc, body = pdu[0], pdu[1:]
    size = _TABLE_SIZE[fc]
    ranges = [(body[0] << 8 | body[1], 1 if fc in (5, 6) else body[2] << 8 | body[3])]
    if fc == _FC_READ_WRITE:
        ranges.append((body[4] << 8 | body[5], body[6] << 8 | body[7]))
    if any(start + count > size for start, count in ranges):
        return ExcCodes.ILLEGAL_ADDRESS
    return None


def _check_value(pdu: bytes) -> ExcCodes | None:
    """Function code (01) and quantity / length / value (03) checks of :func:`check_pdu`."""
    fc = pdu[0]
    if fc not in _SERVED_FCS:
        return ExcCodes.ILLEGAL_FUNCTION
    body = pdu[1:]

    def word(i: int) -> int:
        return body[i] << 8 | body[i + 1]

    if fc in (1, 2, 3, 4, 5, 6):
        if len(body) != 4:
            return ExcCodes.ILLEGAL_VALUE
        limit = {1: 2000, 2: 2000, 3: 125, 4: 125}.get(fc)
        if limit is not None and not 1 <= word(2) <= limit:
            return ExcCodes.ILLEGAL_VALUE
        if fc == _FC_WRITE_COIL and word(2) not in (0x0000, 0xFF00):
            return ExcCodes.ILLEGAL_VALUE
        return None
    if fc in (_FC_WRITE_COILS, _FC_WRITE_REGS):
        if len(body) < 5:
            return ExcCodes.ILLEGAL_VALUE
        count, nbytes = word(2), body[4]
        limit, need = (1968, (count + 7) // 8) if fc == _FC_WRITE_COILS else (123, 2 * count)
        if not 1 <= count <= limit or nbytes != need or len(body) != 5 + nbytes:
            return ExcCodes.ILLEGAL_VALUE
        return None
    # FC23 read/write multiple registers: read 1..125, write 1..121
    if len(body) < 9:
        return ExcCodes.ILLEGAL_VALUE
    read, write, nbytes = word(2), word(6), body[8]
    if not 1 <= read <= 125 or not 1 <= write <= 121 or nbytes != 2 * write or len(body) != 9 + nbytes:
        return ExcCodes.ILLEGAL_VALUE
    return None


_READ_FCS = frozenset({_FC_READ_COILS, _FC_READ_DI, _FC_READ_HR, _FC_READ_IR})


@dataclass(frozen=True)
class _Read:
    """A checked read request (FC 1-4), answered from the controller without pymodbus' request machinery:
    at ~35 µs a request that machinery made 1 MiB of pipelined FC4 reads cost 3.3 s of CPU."""

    tid: int
    unit: int
    pdu: bytes


def read_reply(controller: FieldbusController, pdu: bytes) -> bytes:
    """The reply PDU to a read request ``pdu`` that :func:`check_pdu` passed (Modbus Application Protocol
    §6.1-6.4: function code, byte count, then registers big-endian or bits packed LSB first)."""
    fc = pdu[0]
    start, count = pdu[1] << 8 | pdu[2], pdu[3] << 8 | pdu[4]
    if fc in (_FC_READ_HR, _FC_READ_IR):
        regs = controller.output_image.registers() if fc == _FC_READ_HR else controller.input_image().registers()
        return struct.pack(f">BB{count}H", fc, 2 * count, *regs[start:start + count])
    bits = controller.output_image.coils() if fc == _FC_READ_COILS else controller.input_image().discrete_inputs()
    chosen = bits[start:start + count]
    packed = bytes(int_of(chosen[i:i + 8]) for i in range(0, count, 8))
    return bytes((fc, len(packed))) + packed


def _words(bits: list[bool]) -> list[int]:
    """Bits packed 16 per register, bit 0 first (pymodbus' bit-block layout)."""
    return [int_of(bits[i:i + 16]) for i in range(0, len(bits), 16)]


class FieldbusModbusAdapter:
    """Maps pymodbus' SimDevice action onto a :class:`FieldbusController`."""

    def __init__(self, controller: FieldbusController) -> None:
        self.controller = controller
        self.requests = 0
        self.last_write: float | None = None  # time.time() of the last write a master made

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
            if set_values is not None:
                self.last_write = time.time()
        except (ValueError, IndexError):
            return ExcCodes.ILLEGAL_VALUE
        except Exception:  # never let a device error kill the bus: report it as a device failure
            log.exception("fieldbus write failed")
            return ExcCodes.DEVICE_FAILURE
        self._refresh(function_code, registers)
        return None

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


class _Connection(ServerRequestHandler):
    """One Modbus/TCP connection, framed by its MBAP headers (works around pymodbus 3.16).

    pymodbus 3.16 answers only the first of several requests that arrive in one TCP segment (the
    rest wait for the next segment), stalls a connection for good after a non-zero protocol id,
    buffers whatever length an MBAP header claims, and answers malformed PDUs with exception 01.
    Here every complete ADU in the stream is cut by its length field and answered in order;
    protocol id ≠ 0 and length < 2 ADUs are dropped unanswered (nothing to answer: not Modbus, no
    function code); a length > 254 closes the connection (the stream cannot be framed); PDUs are
    checked by :func:`check_pdu` before pymodbus decodes and executes them. Requests before an
    unframeable ADU are answered before the connection closes.
    """

    def __init__(self, owner: ModbusTcpServer) -> None:
        super().__init__(owner, None, None, None)  # type: ignore[no-untyped-call]
        self.max_buffer_size = RECV_BUFFER_LIMIT
        self._queue: deque[ModbusPDU | _Read] = deque()
        self._worker: asyncio.Task[None] | None = None
        self._paused = False
        self._closing = False   # an unframeable ADU came: answer what is queued, then close
        self._buf = bytearray()  # received, not yet framed (at most one read plus a partial ADU)
        self._partial: asyncio.TimerHandle | None = None  # the deadline of the partial ADU in _buf

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        super().connection_made(transport)
        listener = getattr(self, "listener", None)
        peer = _host(transport)
        limit = getattr(listener, "peer_limit", None)
        if listener is None or peer is None or limit is None:
            return
        same = sum(1 for c in list(listener.active_connections.values())
                   if c is not self and c.transport is not None and _host(c.transport) == peer)
        if same >= limit:
            listener.refused_peers += 1
            if listener.refused_peers % 100 == 1:
                log.warning("Modbus/TCP: connection from %s refused: it holds %d of the %d a peer may "
                            "(%d refused so far)", peer, same, limit, listener.refused_peers)
            self.close()

    def data_received(self, data: bytes) -> None:
        """Our own buffer: pymodbus' ``send()`` empties its receive buffer on every reply, which cut a
        partial ADU of a long pipelined write (6,000 requests: 2,728 answered, then silence)."""
        if self._closing:
            return
        self._buf += data
        self._cut()

    def callback_data(self, data: bytes, addr: tuple[str, int] | None = None) -> int:
        """pymodbus' hook (unused for TCP, :meth:`data_received` frames): take ``data`` whole."""
        if not self._closing:
            self._buf += data
            self._cut()
        return len(data)

    def _cut(self) -> None:
        """Frame complete ADUs into the queue until :data:`MAX_QUEUED` wait: the work per loop turn is
        bounded however much one read brought; the rest stays buffered and reading pauses."""
        buf = self._buf
        pos = 0
        while len(self._queue) < MAX_QUEUED and len(buf) - pos >= 6:
            tid, protocol, length = struct.unpack_from(">HHH", buf, pos)
            if length > MAX_MBAP_LENGTH:
                log.warning("Modbus/TCP: MBAP length %d > %d, closing the connection", length, MAX_MBAP_LENGTH)
                buf.clear()
                self._close_when_answered()
                return
            if len(buf) - pos < 6 + length:
                break   # the rest of this ADU is still on its way
            frame = bytes(buf[pos + 6:pos + 6 + length])
            pos += 6 + length
            if protocol != 0 or length < 2:
                log.debug("Modbus/TCP: dropped ADU tid=%d protocol=%d length=%d", tid, protocol, length)
                continue
            self._submit(tid, frame[0], frame[1:])
        del buf[:pos]
        if pos and self._partial is not None:  # an ADU completed: the deadline was for it
            self._partial.cancel()
            self._partial = None
        if buf and self._partial is None and len(self._queue) < MAX_QUEUED:
            self._partial = asyncio.get_running_loop().call_later(ADU_DEADLINE, self._too_slow)
        backlog = len(self._queue) >= MAX_QUEUED or len(buf) > 6 + MAX_MBAP_LENGTH
        if backlog and not self._paused:
            self._paused = True
            self._reading(False)

    def _too_slow(self) -> None:
        """The partial ADU missed :data:`ADU_DEADLINE`: answer what is queued, then close."""
        self._partial = None
        if self._buf and not self._closing:
            log.info("Modbus/TCP: an ADU was not complete %.0f s after its first byte; closing the connection",
                     ADU_DEADLINE)
            self._buf.clear()
            self._close_when_answered()

    def connection_lost(self, exc: Exception | None) -> None:
        if self._partial is not None:
            self._partial.cancel()
            self._partial = None
        super().connection_lost(exc)

    def _submit(self, tid: int, unit: int, pdu: bytes) -> None:
        request: ModbusPDU | _Read | None = None
        code = check_pdu(pdu)
        if code is None and pdu[0] in _READ_FCS:
            request = _Read(tid, unit, pdu)
        elif code is None:
            request = self.framer.decoder.decode(pdu)
            if request is None:
                code = ExcCodes.ILLEGAL_FUNCTION
        if request is None:
            request = ExceptionResponse(pdu[0] & 0x7F, int(code or ExcCodes.ILLEGAL_FUNCTION), unit, tid)
        if not isinstance(request, _Read):
            request.dev_id, request.transaction_id = unit, tid
        self._queue.append(request)
        if self._worker is None or self._worker.done():
            self._worker = asyncio.get_running_loop().create_task(self._drain())

    def _close_when_answered(self) -> None:
        """Stop reading; close once the requests already queued are answered (fuzz F2)."""
        self._closing = True
        self._reading(False)
        if not self._queue and (self._worker is None or self._worker.done()):
            self.close()

    async def _drain(self) -> None:
        """Execute queued requests one by one, so replies leave in request order."""
        adapter: FieldbusModbusAdapter = self.server.adapter
        replies = bytearray()   # read replies of this loop turn, written together
        cache: dict[bytes, bytes] = {}  # read PDU -> reply PDU, within one turn (the images cannot change)
        try:
            n = 0
            while self._queue:
                request = self._queue.popleft()
                if isinstance(request, _Read):
                    reply = cache.get(request.pdu)
                    if reply is None:
                        reply = cache[request.pdu] = read_reply(adapter.controller, request.pdu)
                    adapter.requests += 1
                    replies += struct.pack(">HHHB", request.tid, 0, len(reply) + 1, request.unit) + reply
                    n += 1
                    if n % 256 == 0:
                        self._flush(replies)
                        cache.clear()
                        await asyncio.sleep(0)  # other clients get a turn during a long pipelined read
                else:
                    self._flush(replies)
                    cache.clear()
                    if isinstance(request, ExceptionResponse):
                        self.server_send(request, None)  # type: ignore[no-untyped-call]
                    else:
                        self.last_pdu, self.last_addr = request, None
                        await self.handle_request()  # type: ignore[no-untyped-call]
                    n += 1
                    if n % 16 == 0:
                        await asyncio.sleep(0)  # other clients get a turn during a long pipelined write
                if not self._closing and len(self._queue) < MAX_QUEUED // 2:
                    if self._buf:
                        self._cut()  # buffered ADUs of a long write, before reading more
                    if self._paused and len(self._queue) < MAX_QUEUED // 2 and len(self._buf) <= 6 + MAX_MBAP_LENGTH:
                        self._paused = False
                        self._reading(True)
        finally:
            self._flush(replies)
            if self._closing:
                self.close()

    def _flush(self, replies: bytearray) -> None:
        """Write the read replies gathered so far, in request order, before anything else is answered."""
        if replies:
            transport = self.transport
            if transport is not None and not transport.is_closing():
                transport.write(bytes(replies))  # type: ignore[attr-defined]
            replies.clear()

    def _reading(self, on: bool) -> None:
        """Pause / resume reading the socket (back-pressure while requests are queued)."""
        transport = self.transport
        if isinstance(transport, asyncio.ReadTransport) and not transport.is_closing():
            if on:
                transport.resume_reading()
            else:
                transport.pause_reading()


def _host(transport: Any) -> str | None:
    """The peer's address (without port) of a connection's transport."""
    peer = transport.get_extra_info("peername") if transport is not None else None
    return str(peer[0]) if isinstance(peer, tuple) and peer else None


class _Server(ModbusTcpServer):
    """pymodbus' TCP server with our connection class."""

    adapter: FieldbusModbusAdapter
    peer_limit: int | None = None
    """Connections one peer address may hold (:data:`PEER_SHARE` of the cap); None: no limit."""
    refused_peers = 0

    def callback_new_connection(self) -> _Connection:
        return _Connection(self)


@dataclass
class ModbusHandle:
    """A running Modbus/TCP fieldbus server: the controller's :class:`~pywsg.fieldbus.bus.BusAdapter`
    for Modbus/TCP. ``port`` is the bound port (useful with port 0)."""

    host: str
    port: int
    controller: FieldbusController
    server: Any = field(repr=False)
    adapter: FieldbusModbusAdapter = field(repr=False)
    owns_controller: bool = field(default=False, repr=False)   # serve_modbus made it: close() closes it
    name: str = "Modbus/TCP"

    @property
    def output_image(self) -> OutputImage:
        """The output image last written by the PLC."""
        return self.controller.output_image

    def input_image(self) -> InputImage:
        """The input image now."""
        return self.controller.input_image()

    @property
    def masters(self) -> int:
        """Modbus/TCP connections open now (the Fieldbus Monitor's Interface state)."""
        return len(getattr(self.server, "active_connections", None) or {})

    @property
    def last_write(self) -> float | None:
        """``time.time()`` of the last write a master made, None before the first."""
        return self.adapter.last_write

    def bus_state(self) -> dict[str, str]:
        """The Fieldbus Monitor's Bus State rows (003 §6) for Modbus/TCP.

        "Interface state" is Online while a master is connected (with the age of its last write),
        Waiting with none (docs/fidelity.md "Interface state"). Modbus/TCP has no station address or
        bitrate: the rows say what stands in their place.
        """
        masters = self.masters
        last = self.last_write
        ago = "no write yet" if last is None else f"last write {max(0.0, time.time() - last):.1f} s ago"
        if masters:
            state = f"Online: {masters} master{'' if masters == 1 else 's'} connected, {ago}"
        else:
            state = f"Waiting: no Modbus master connected ({ago})"
        return {"Interface": f"Modbus/TCP (port {self.port})", "Unit id": "any (the WSG answers every unit id)",
                "Interface state": state}

    async def close(self) -> None:
        """Stop serving and detach from the controller (closed too if ``serve_modbus`` made it)."""
        self.controller.detach_bus(self)
        await self.server.shutdown()
        if self.owns_controller:
            self.controller.close()
        await asyncio.sleep(0)


async def serve_modbus(gripper: Any, host: str = "0.0.0.0", port: int = STANDARD_PORT,
                       controller: FieldbusController | None = None, max_connections: int = 32,
                       idle_timeout: float | None = None) -> ModbusHandle:
    """Serve ``gripper``'s fieldbus interface over Modbus/TCP on ``host:port`` (port 0: any free port).

    ``controller``: the gripper's :class:`FieldbusController` when other buses share it (the sim makes
    one per gripper); without one, a controller of its own is made and closed with the server.
    Runs on the current event loop; the gripper must be polled by a runner (e.g.
    ``pywsg.server.DeviceRunner``) so motions finish. Raises OSError if the port cannot be bound.
    At most ``max_connections`` masters at a time; more are refused (``pywsg.server.conncap``); one
    sending nothing for ``idle_timeout`` s is closed (None: never), and so is one whose request is not
    whole :data:`ADU_DEADLINE` s after its first byte. One peer address holds at most
    :data:`PEER_SHARE` of ``max_connections`` (at least one) so other masters always find a slot.
    """
    owns = controller is None
    ctl = controller or FieldbusController(gripper)
    adapter = FieldbusModbusAdapter(ctl)
    server = _Server(adapter.device(), address=(host, port))
    server.peer_limit = max(1, int(max_connections * PEER_SHARE))
    server.adapter = adapter
    cap_modbus_server(server, max_connections, idle_timeout)
    # Bind ourselves first so a busy port raises OSError (pymodbus only logs and returns False).
    if not await server.listen():
        if owns:
            ctl.close()
        raise OSError(f"cannot listen for Modbus/TCP on {host}:{port}")
    sockets = getattr(server.transport, "sockets", None) or []
    bound = sockets[0].getsockname()[1] if sockets else port
    log.info("Modbus/TCP fieldbus on %s:%d", host, bound)
    handle = ModbusHandle(host, bound, ctl, server, adapter, owns)
    ctl.attach_bus(handle)
    return handle
