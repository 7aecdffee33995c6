"""The device's connection manager: Connect, Read, Write, Control, Release (IEC 61158-6-10 CMRPC), sans-IO.

One IO AR (IOCARSingle: input and output IOCR, alarm CR, expected submodules) and one device-access
AR (IOSAR, records only) at a time; a second controller asking for the IO AR is refused with
PNIOStatus DB 81 40 04 ("out of AR resources") and the AR in use is left alone.

The real configuration (also in the GSDML, :mod:`pywsg.fieldbus.descriptions`): slot 0 is the
device access point (subslot 1, interface 8000h, port 8001h), slot 1 the WSG module with the
manuals' 12 input and 8 output bytes (002 §3.1, 003 §4.1).
"""

from __future__ import annotations

import enum
import logging
import struct
import time
import uuid
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Protocol

from . import blocks as b
from . import diagnosis as dg
from . import rpc
from .im import Identity as Identity  # re-exported: ConnectionManager takes one
from .im import IMRecords
from .pdev import PDevRecords
from .refusals import RefusalLog
from .station import Station

log = logging.getLogger(__name__)

API = 0
DAP_MODULE, DAP_SUBMODULE, INTERFACE_SUBMODULE, PORT_SUBMODULE = 0x00000001, 0x00000001, 0x00000002, 0x00000003
WSG_MODULE, WSG_SUBMODULE = 0x00000010, 0x00000011
INPUT_LENGTH, OUTPUT_LENGTH = 12, 8
#: Shortest cycle the device accepts, in 31.25 µs units (GSDML MinDeviceInterval; docs/benchmarks.md).
MIN_DEVICE_INTERVAL = 64
WRITE_MULTIPLE = 0xE040

NO_RECORD = b.RecordRequest(0, uuid.UUID(int=0), 0, 0, 0, 0, 0)
# PNIOStatus: ErrorCode (DBh connect, DCh release, DDh control, DEh read, DFh write), ErrorDecode, code1, code2
OK = 0


def pnio_status(code: int, decode: int, code1: int, code2: int) -> int:
    return code << 24 | decode << 16 | code1 << 8 | code2


CONNECT_ERR, RELEASE_ERR, CONTROL_ERR, READ_ERR, WRITE_ERR = 0xDB, 0xDC, 0xDD, 0xDE, 0xDF
#: PNIOStatus ErrorCode of a refused request, per operation (IEC 61158-6-10 ErrorCode: DBh Connect,
#: DCh Release, DDh Control, DEh Read and ReadImplicit, DFh Write).
OP_ERROR = {rpc.OP_CONNECT: CONNECT_ERR, rpc.OP_RELEASE: RELEASE_ERR, rpc.OP_READ: READ_ERR,
            rpc.OP_WRITE: WRITE_ERR, rpc.OP_CONTROL: CONTROL_ERR, rpc.OP_READ_IMPLICIT: READ_ERR}
OP_NAME = {rpc.OP_CONNECT: "Connect", rpc.OP_RELEASE: "Release", rpc.OP_READ: "Read", rpc.OP_WRITE: "Write",
           rpc.OP_CONTROL: "Control", rpc.OP_READ_IMPLICIT: "ReadImplicit"}
PNIO, PNIORW = 0x81, 0x80
CMRPC_ARGS_LENGTH, CMRPC_UNKNOWN_BLOCKS, CMRPC_IOCR_MISSING, CMRPC_ALARM_CR, CMRPC_OUT_OF_AR, \
    CMRPC_AR_UUID_UNKNOWN, CMRPC_STATE_CONFLICT = range(7)
# PNIORW ErrorCode1 (error class << 4 | code): invalid index, write length, invalid slot/subslot, state conflict
RW_INVALID_INDEX, RW_WRITE_LENGTH, RW_INVALID_SLOT = 0xB0, 0xB1, 0xB2
RW_STATE_CONFLICT, RW_INVALID_RANGE, RW_INVALID_PARAMETER = 0xB5, 0xB7, 0xB8


@dataclass(frozen=True)
class Submodule:
    slot: int
    subslot: int
    module_ident: int
    submodule_ident: int
    input_length: int = 0
    output_length: int = 0


REAL = (Submodule(0, 1, DAP_MODULE, DAP_SUBMODULE), Submodule(0, 0x8000, DAP_MODULE, INTERFACE_SUBMODULE),
        Submodule(0, 0x8001, DAP_MODULE, PORT_SUBMODULE),
        Submodule(1, 1, WSG_MODULE, WSG_SUBMODULE, INPUT_LENGTH, OUTPUT_LENGTH))
REAL_BY_ADDR = {(s.slot, s.subslot): s for s in REAL}


class ARState(enum.Enum):
    PARAMETERIZING = "Parameterization"      # Connect done, waiting for PrmEnd
    APPLICATION_READY = "Waiting for ApplicationReady confirmation"
    DATA = "Data exchange"


@dataclass
class AR:
    """One application relation."""

    request: b.ARRequest
    controller_ip: str
    controller_port: int
    input_cr: b.IOCRRequest | None = None
    output_cr: b.IOCRRequest | None = None
    input_frame_id: int = 0
    output_frame_id: int = 0
    alarm: b.AlarmCRRequest | None = None
    #: (slot, subslot) → expected submodule; ``proper``: those that match the real one.
    expected: dict[tuple[int, int], b.ExpectedSubmodule] = field(default_factory=dict)
    proper: set[tuple[int, int]] = field(default_factory=set)
    diff: bytes = b""
    state: ARState = ARState.PARAMETERIZING
    last_activity: float = field(default_factory=time.monotonic)

    @property
    def uuid(self) -> uuid.UUID:
        return self.request.ar_uuid

    @property
    def is_io(self) -> bool:
        return self.request.ar_type == b.AR_TYPE_IOCAR

    @property
    def controller_mac(self) -> bytes:
        return self.request.initiator_mac

    @property
    def wsg_ok(self) -> bool:
        return (1, 1) in self.proper


class RecordHandler(Protocol):
    """Owner of some records (:mod:`.im`, :mod:`.pdev`): ``read`` gives the record or None (not mine),
    ``write`` 0, a PNIORW ErrorCode1, or None (not mine). ``ar``: the request's AR, if any;
    ``real``: the address is a real submodule."""

    def read(self, req: b.RecordRequest, ar: AR | None, real: bool) -> bytes | None: ...

    def write(self, req: b.RecordRequest, ar: AR | None, data: bytes) -> int | None: ...


class DiagnosisRecords:
    """The diagnosis records (800Ah … F80Ch, :mod:`.diagnosis`): the WSG submodule's active channel
    diagnosis from 002 §3.3's error flags in ``sysstate()`` (SYSSTATE now). A :class:`RecordHandler`."""

    def __init__(self, sysstate: Callable[[], int]) -> None:
        self.sysstate = sysstate

    def read(self, req: b.RecordRequest, ar: AR | None, real: bool) -> bytes | None:
        if req.index not in dg.RECORDS:
            return None
        if req.index in dg.SUBSLOT_RECORDS + dg.SLOT_RECORDS and not real:
            return None
        if req.index in dg.AR_RECORDS and (ar is None or (ar.is_io and not ar.wsg_ok)):
            return None if ar is None else b""
        if not dg.covers_wsg(req.index, req.slot, req.subslot):
            return b""
        return dg.diagnosis_data(API, self.sysstate())

    def write(self, req: b.RecordRequest, ar: AR | None, data: bytes) -> int | None:
        return None   # read only: the index is refused as invalid


@dataclass
class Listener:
    """What the device does on AR events (set by :class:`pywsg.fieldbus.profinet.device.ProfinetDevice`)."""

    connected: Callable[[AR], None] = lambda ar: None
    prm_end: Callable[[AR], None] = lambda ar: None
    released: Callable[[AR, str], None] = lambda ar, why: None
    write_record: Callable[[b.RecordRequest, bytes], int] | None = None


class ConnectionManager:
    """Answers PNIO RPC requests; :meth:`handle` returns the reply datagram (or None: no reply)."""

    def __init__(self, station: Station, identity: Identity, listener: Listener | None = None) -> None:
        self.station = station
        self.identity = identity
        self.listener = listener or Listener()
        self.io_ar: AR | None = None
        self.access_ar: AR | None = None
        self.boot_time = int(time.time()) & 0xFFFFFFFF
        self.refused = 0   # Connect requests refused (for the Fieldbus Monitor)
        self._next_frame_id = 0xC100
        self.alarm_ref = 0x0001   # our LocalAlarmReference in every AlarmCRBlockRes
        # who answers which record (asked in order; each returns None for an index not its own)
        self.im = IMRecords(station, identity, dap_module=DAP_MODULE, dap_submodule=DAP_SUBMODULE)
        self.pdev = PDevRecords(station, REAL)
        self.records: list[RecordHandler] = [self.im, self.pdev]
        # last replies by (activity, seqnum): a retransmitted request gets the same answer, not a second action
        self._replies: dict[tuple[uuid.UUID, int], bytes] = {}
        self.refusals = RefusalLog(log)
        #: SYSSTATE now (the device sets it): the diagnosis records' source.
        self.sysstate: Callable[[], int] = lambda: 0
        self.records.append(DiagnosisRecords(lambda: self.sysstate()))

    def _refused(self, op: str, why: str) -> None:
        self.refusals.warn("PROFINET: %s refused: %s", op, why)

    # --- dispatch -------------------------------------------------------------------------------
    def handle(self, data: bytes, src_ip: str, sport: int) -> bytes | None:
        parsed = rpc.parse(data)
        if parsed is None:
            return None
        hdr, body = parsed
        if hdr.ptype != rpc.REQUEST:
            return None   # acks, pings, responses to our CControl are handled elsewhere
        key = (hdr.activity, hdr.seqnum)
        if key in self._replies:
            return self._replies[key]
        if hdr.flags1 & rpc.FLAG_FRAG:
            reply = rpc.reject(hdr, rpc.NCA_PROTO_ERROR, self.boot_time)
        elif hdr.interface == rpc.UUID_EPM:
            reply = rpc.reject(hdr, rpc.NCA_OP_RNG_ERROR, self.boot_time)
        elif hdr.interface != rpc.UUID_DEVICE:
            reply = rpc.reject(hdr, rpc.NCA_UNK_IF, self.boot_time)
        elif hdr.opnum > rpc.OP_READ_IMPLICIT:
            reply = rpc.reject(hdr, rpc.NCA_OP_RNG_ERROR, self.boot_time)
        else:
            ndr = rpc.parse_ndr(body, hdr.little)
            if ndr is None:
                status, args, maximum = pnio_status(OP_ERROR[hdr.opnum], PNIO, 0x40, CMRPC_ARGS_LENGTH), b"", 0
                self._refused(OP_NAME[hdr.opnum], "NDR header does not fit the request")
            else:
                maximum = ndr.args_maximum
                status, args = self._operation(hdr.opnum, ndr.args, src_ip, sport)
                if len(args) > maximum:
                    # the answer does not fit the controller's buffer (ArgsMaximum): CMRPC "args length
                    # invalid", no blocks (a cut block would lie about its length)
                    status, args = pnio_status(OP_ERROR[hdr.opnum], PNIO, 0x40, CMRPC_ARGS_LENGTH), b""
            if hdr.opnum == rpc.OP_WRITE and status != OK and not args:
                # a Write answer is an IODWriteResHeader, refused or not (Wireshark: Malformed without one);
                # for a request too broken to name its record, one with zero fields carries the status
                args = b.write_response(NO_RECORD, status)
            reply = rpc.response(hdr, rpc.ndr_response(status, args, maximum, little=True), self.boot_time)
        if len(self._replies) >= 16:
            self._replies.pop(next(iter(self._replies)))
        self._replies[key] = reply
        return reply

    def _operation(self, op: int, args: bytes, src_ip: str, sport: int) -> tuple[int, bytes]:
        try:
            if op == rpc.OP_CONNECT:
                return self._connect(args, src_ip, sport)
            if op == rpc.OP_RELEASE:
                return self._control(args, RELEASE_ERR)
            if op == rpc.OP_CONTROL:
                return self._control(args, CONTROL_ERR)
            if op in (rpc.OP_READ, rpc.OP_READ_IMPLICIT):
                return self._read(args, implicit=op == rpc.OP_READ_IMPLICIT)
            return self._write(args)
        except b.BlockError as exc:
            self._refused(OP_NAME[op], str(exc))
            if op == rpc.OP_CONNECT:
                self.refused += 1
            return pnio_status(OP_ERROR[op], PNIO, exc.code1, exc.code2), b""

    # --- connect --------------------------------------------------------------------------------
    def _connect(self, args: bytes, src_ip: str, sport: int) -> tuple[int, bytes]:
        ar_req: b.ARRequest | None = None
        iocrs: list[b.IOCRRequest] = []
        alarm: b.AlarmCRRequest | None = None
        expected: list[b.ExpectedSubmodule] = []
        for btype, body in b.split(args):
            if btype == b.AR_REQ:
                if ar_req is not None:
                    raise b.BlockError(0x40, CMRPC_UNKNOWN_BLOCKS, "two ARBlockReq")
                ar_req = b.parse_ar(body)
            elif btype == b.IOCR_REQ:
                iocrs.append(b.parse_iocr(body))
            elif btype == b.ALARM_CR_REQ:
                if alarm is not None:
                    raise b.BlockError(0x40, CMRPC_ALARM_CR, "two AlarmCRBlockReq")
                alarm = b.parse_alarm_cr(body)
            elif btype == b.EXP_SUBMOD_REQ:
                expected.extend(b.parse_expected(body))
            # other blocks (PrmServer, ARRPC, ARVendor, IRInfo): not used by an RT_CLASS_1 device
        if ar_req is None:
            raise b.BlockError(0x40, CMRPC_UNKNOWN_BLOCKS, "no ARBlockReq")
        ar = AR(ar_req, src_ip, sport, alarm=alarm)
        if ar_req.ar_type == b.AR_TYPE_IOSAR:
            if self.access_ar is not None and self.access_ar.uuid != ar.uuid:
                raise b.BlockError(0x40, CMRPC_OUT_OF_AR, "a device-access AR is already established")
            self.access_ar = ar
            ar.state = ARState.DATA
            log.info("PROFINET: device-access AR from %s (%s)", src_ip, ar_req.station_name)
            return OK, b.ar_response(ar_req, self.station.mac)
        if self.io_ar is not None:
            raise b.BlockError(0x40, CMRPC_OUT_OF_AR,
                               f"IO AR in use by {self.io_ar.controller_ip} ({self.io_ar.request.station_name})")
        inputs = [c for c in iocrs if c.iocr_type == b.IOCR_INPUT]
        outputs = [c for c in iocrs if c.iocr_type == b.IOCR_OUTPUT]
        if len(inputs) != 1 or len(outputs) != 1:
            raise b.BlockError(0x40, CMRPC_IOCR_MISSING, "an IO AR needs one input and one output IOCR")
        if alarm is None:
            raise b.BlockError(0x40, CMRPC_ALARM_CR, "an IO AR needs an AlarmCRBlockReq")
        for cr in iocrs:
            interval = cr.send_clock_factor * cr.reduction_ratio
            if interval < MIN_DEVICE_INTERVAL:
                raise b.BlockError(0x02, 11, f"cycle {interval * 31.25 / 1000:g} ms is shorter than the device "
                                             f"interval {MIN_DEVICE_INTERVAL * 31.25 / 1000:g} ms")
        ar.input_cr, ar.output_cr = inputs[0], outputs[0]
        self._check_expected(ar, expected)
        self._check_layout(ar)
        ar.input_frame_id = ar.input_cr.frame_id if ar.input_cr.frame_id != 0xFFFF else self._frame_id()
        ar.output_frame_id = ar.output_cr.frame_id if ar.output_cr.frame_id != 0xFFFF else self._frame_id()
        self.io_ar = ar
        reply = (b.ar_response(ar_req, self.station.mac)
                 + b.iocr_response(ar.input_cr, ar.input_frame_id) + b.iocr_response(ar.output_cr, ar.output_frame_id)
                 + b.alarm_cr_response(alarm, self.alarm_ref, min(alarm.max_data_length, 200)) + ar.diff)
        log.info("PROFINET: AR from %s (%s, %s), cycle %g ms", src_ip, ar_req.station_name,
                 ":".join(f"{x:02x}" for x in ar_req.initiator_mac), ar.output_cr.cycle_s * 1000)
        self.listener.connected(ar)
        return OK, reply

    def _frame_id(self) -> int:
        fid = self._next_frame_id
        self._next_frame_id = 0xC100 + (self._next_frame_id - 0xC100 + 1) % 0x100
        return fid

    @staticmethod
    def _check_expected(ar: AR, expected: list[b.ExpectedSubmodule]) -> None:
        modules: dict[int, b.DiffModule] = {}
        for e in expected:
            key = (e.slot, e.subslot)
            ar.expected[key] = e
            real = REAL_BY_ADDR.get(key)
            real_module = next((s.module_ident for s in REAL if s.slot == e.slot), None)
            if real_module is None:
                modules.setdefault(e.slot, b.DiffModule(e.slot, e.module_ident, b.NO_MODULE))
                continue
            if real is None:
                m = modules.setdefault(e.slot, b.DiffModule(e.slot, real_module, b.PROPER_MODULE))
                m.submodules.append((e.subslot, e.submodule_ident, b.IDENT_NO_SUBMODULE))
                continue
            wrong_module = real_module != e.module_ident
            wrong_sub = (real.submodule_ident != e.submodule_ident or real.input_length != e.input_length
                         or real.output_length != e.output_length)
            if wrong_module or wrong_sub:
                m = modules.setdefault(e.slot, b.DiffModule(
                    e.slot, real_module, b.WRONG_MODULE if wrong_module else b.PROPER_MODULE))
                m.submodules.append((e.subslot, real.submodule_ident, b.IDENT_WRONG))
            else:
                ar.proper.add(key)
        if modules:
            ar.diff = b.module_diff(API, sorted(modules.values(), key=lambda m: m.slot))
            log.warning("PROFINET: expected configuration differs from the real one (slots %s): ModuleDiff sent",
                        ", ".join(str(s) for s in sorted(modules)))

    @staticmethod
    def _check_layout(ar: AR) -> None:
        """Every object inside DataLength: the frame codec may then slice without checks."""
        for cr in (ar.input_cr, ar.output_cr):
            assert cr is not None
            for obj in cr.data:
                exp = ar.expected.get((obj.slot, obj.subslot))
                length = 0 if exp is None else (exp.input_length if cr.iocr_type == b.IOCR_INPUT else exp.output_length)
                if obj.offset + length + 1 > cr.data_length:
                    raise b.BlockError(0x02, 8, f"IO data object {obj.slot}/{obj.subslot} beyond DataLength")
            for obj in cr.iocs:
                if obj.offset + 1 > cr.data_length:
                    raise b.BlockError(0x02, 8, f"IOCS {obj.slot}/{obj.subslot} beyond DataLength")

    # --- control / release ----------------------------------------------------------------------
    def _find(self, ar_uuid: uuid.UUID) -> AR | None:
        for ar in (self.io_ar, self.access_ar):
            if ar is not None and ar.uuid == ar_uuid:
                return ar
        return None

    def _control(self, args: bytes, err: int) -> tuple[int, bytes]:
        btype, body = next(b.split(args), (0, b""))
        ctl = b.parse_control(body, btype)
        ar = self._find(ctl.ar_uuid)
        if ar is None or ar.request.session_key != ctl.session_key:
            return pnio_status(err, PNIO, 0x40, CMRPC_AR_UUID_UNKNOWN), b""
        ar.last_activity = time.monotonic()
        if btype == b.RELEASE_REQ and ctl.command == b.CMD_RELEASE:
            self.drop(ar, "released by the controller")
        elif btype == b.PRM_END_REQ and ctl.command == b.CMD_PRM_END:
            if ar.state != ARState.PARAMETERIZING:
                return pnio_status(err, PNIO, 0x40, CMRPC_STATE_CONFLICT), b""
            ar.state = ARState.APPLICATION_READY
            self.listener.prm_end(ar)
        elif btype == b.PRM_BEGIN_REQ and ctl.command == b.CMD_PRM_BEGIN:
            ar.state = ARState.PARAMETERIZING
        else:
            return pnio_status(err, PNIO, 0x40, CMRPC_UNKNOWN_BLOCKS), b""
        return OK, b.control(btype | b.RESPONSE_BIT, ctl.ar_uuid, ctl.session_key, b.CMD_DONE)

    def drop(self, ar: AR, why: str) -> None:
        """End an AR (release, watchdog, abort); the listener is told why."""
        if ar is self.io_ar:
            self.io_ar = None
        elif ar is self.access_ar:
            self.access_ar = None
        else:
            return
        log.info("PROFINET: AR of %s ended: %s", ar.controller_ip, why)
        self.listener.released(ar, why)

    # --- records --------------------------------------------------------------------------------
    def _read(self, args: bytes, implicit: bool) -> tuple[int, bytes]:
        btype, body = next(b.split(args), (0, b""))
        if btype != b.READ_REQ:
            return pnio_status(READ_ERR, PNIORW, RW_INVALID_PARAMETER, 0), b""
        req = b.parse_record(body)
        ar = None
        if not implicit:
            ar = self._find(req.ar_uuid)
            if ar is None:
                return pnio_status(READ_ERR, PNIO, 0x40, CMRPC_AR_UUID_UNKNOWN), b""
            ar.last_activity = time.monotonic()
        data = self.record(req)
        if data is None:
            code = RW_INVALID_SLOT if (req.slot, req.subslot) not in REAL_BY_ADDR and req.index < 0xE000 \
                else RW_INVALID_INDEX
            return pnio_status(READ_ERR, PNIORW, code, 0), b""
        if len(data) > req.length:
            # the record does not fit the controller's RecordDataLength: refused whole ("access: invalid
            # range"), never a block cut short whose length field promises more (docs/fidelity.md)
            self._refused("Read", f"record {req.index:#06x} is {len(data)} bytes, RecordDataLength {req.length}")
            return pnio_status(READ_ERR, PNIORW, RW_INVALID_RANGE, 0), b""
        return OK, b.read_response(req, data)

    def record(self, req: b.RecordRequest) -> bytes | None:
        """The record a Read asks for, or None (invalid index or slot)."""
        if req.api != API:
            return None
        ar, real = self._find(req.ar_uuid), (req.slot, req.subslot) in REAL_BY_ADDR
        for handler in self.records:
            data = handler.read(req, ar, real)
            if data is not None:
                return data
        return None

    def _write(self, args: bytes) -> tuple[int, bytes]:
        it = b.split(args)
        btype, body = next(it, (0, b""))
        if btype != b.WRITE_REQ:
            return pnio_status(WRITE_ERR, PNIORW, RW_INVALID_PARAMETER, 0), b""
        req = b.parse_record(body)

        def answer(status: int) -> tuple[int, bytes]:   # a refused Write too carries its IODWriteResHeader
            return status, b.write_response(req, status)

        ar = self._find(req.ar_uuid)
        if ar is None:
            return answer(pnio_status(WRITE_ERR, PNIO, 0x40, CMRPC_AR_UUID_UNKNOWN))
        ar.last_activity = time.monotonic()
        data = args[64:64 + req.length]
        if len(data) != req.length:
            return answer(pnio_status(WRITE_ERR, PNIORW, RW_WRITE_LENGTH, 0))
        if req.index != WRITE_MULTIPLE:
            return answer(self._write_one(req, data))
        # WriteMultiple: a sequence of write headers + data, each padded to 4 bytes
        out, off, worst = [], 0, OK
        while off + 64 <= len(data):
            sub_type, sub_len = struct.unpack_from("!HH", data, off)
            if sub_type != b.WRITE_REQ or sub_len != 60:
                return answer(pnio_status(WRITE_ERR, PNIORW, RW_INVALID_PARAMETER, 0))
            sub = b.parse_record(data[off + 6:off + 64])
            sub_data = data[off + 64:off + 64 + sub.length]
            if len(sub_data) != sub.length:
                return answer(pnio_status(WRITE_ERR, PNIORW, RW_WRITE_LENGTH, 0))
            status = self._write_one(sub, sub_data)
            worst = worst or status
            out.append(b.write_response(sub, status))
            off += 64 + sub.length
            off += -off % 4
        status = pnio_status(WRITE_ERR, PNIORW, 0xB0 | 0x0F, 0) if worst else OK  # DF 80 BF: see each write
        return status, b.write_response(req, status) + b"".join(out)

    def _write_one(self, req: b.RecordRequest, data: bytes) -> int:
        if req.api != API or (req.slot, req.subslot) not in REAL_BY_ADDR:
            return pnio_status(WRITE_ERR, PNIORW, RW_INVALID_SLOT, 0)
        if self.listener.write_record is not None:
            status = self.listener.write_record(req, data)
            if status >= 0:
                return status
        for handler in self.records:
            code1 = handler.write(req, self._find(req.ar_uuid), data)
            if code1 is not None:
                return OK if code1 == 0 else pnio_status(WRITE_ERR, PNIORW, code1, 0)
        return pnio_status(WRITE_ERR, PNIORW, RW_INVALID_INDEX, 0)

    # --- CControl: ApplicationReady ----------------------------------------------------------------
    def application_ready(self, ar: AR, activity: uuid.UUID, seqnum: int) -> bytes:
        """The device's CControl request (IOXControlReq, ApplicationReady) to the controller, little endian."""
        body = b.control(b.APP_READY_REQ, ar.uuid, ar.request.session_key, b.CMD_APP_READY) + ar.diff
        hdr = rpc.RpcHeader(rpc.REQUEST, rpc.FLAG_IDEMPOTENT, 0, rpc.LITTLE_ENDIAN, ar.request.initiator_object,
                            rpc.UUID_CONTROLLER, activity, self.boot_time, 1, seqnum, rpc.OP_CONTROL, 0, 0, 0)
        return rpc.build(hdr, rpc.ndr_request(body, little=True))

    @staticmethod
    def application_ready_done(data: bytes, activity: uuid.UUID) -> bool | None:
        """True: the controller confirmed ApplicationReady; False: it refused; None: not its answer."""
        parsed = rpc.parse(data)
        if parsed is None:
            return None
        hdr, body = parsed
        if hdr.activity != activity or hdr.ptype not in (rpc.RESPONSE, rpc.FAULT, rpc.REJECT):
            return None
        if hdr.ptype != rpc.RESPONSE or len(body) < 4:
            return False
        status: int = struct.unpack_from("<I" if hdr.little else ">I", body)[0]
        return status == OK
