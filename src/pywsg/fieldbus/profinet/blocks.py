"""PNIO blocks of the Connect, Read, Write and Control services (IEC 61158-6-10), sans-IO.

Each block: BlockType (2), BlockLength (2, the bytes after it), BlockVersionHigh/Low, body — big
endian whatever the RPC representation. Parsers raise :class:`BlockError` naming the block and field
index, which the device returns as the PNIOStatus ErrorCode1/ErrorCode2 of a refused Connect.
"""

from __future__ import annotations

import struct
import uuid
from collections.abc import Iterator
from dataclasses import dataclass, field

AR_REQ, IOCR_REQ, ALARM_CR_REQ, EXP_SUBMOD_REQ = 0x0101, 0x0102, 0x0103, 0x0104
AR_RES, IOCR_RES, ALARM_CR_RES, MODULE_DIFF = 0x8101, 0x8102, 0x8103, 0x8104
WRITE_REQ, READ_REQ, WRITE_RES, READ_RES = 0x0008, 0x0009, 0x8008, 0x8009
PRM_END_REQ, APP_READY_REQ, RELEASE_REQ, PRM_BEGIN_REQ = 0x0110, 0x0112, 0x0114, 0x0118
RESPONSE_BIT = 0x8000
CMD_PRM_END, CMD_APP_READY, CMD_RELEASE, CMD_DONE, CMD_PRM_BEGIN = 0x0001, 0x0002, 0x0004, 0x0008, 0x0040

IOCR_INPUT, IOCR_OUTPUT = 1, 2
AR_TYPE_IOCAR, AR_TYPE_IOSAR = 0x0001, 0x0006
#: ErrorCode1 of a Connect refused for a block: the block's number (ARBlockReq 1, IOCRBlockReq 2, ...).
BLOCK_ERROR_CODE1 = {AR_REQ: 0x01, IOCR_REQ: 0x02, ALARM_CR_REQ: 0x03, EXP_SUBMOD_REQ: 0x04}


class BlockError(ValueError):
    """A block that cannot be used; ``code1``/``code2``: PNIOStatus ErrorCode1/ErrorCode2."""

    def __init__(self, code1: int, code2: int, text: str) -> None:
        super().__init__(text)
        self.code1, self.code2 = code1, code2


def header(block_type: int, body: bytes, version: tuple[int, int] = (1, 0)) -> bytes:
    return struct.pack("!HHBB", block_type, len(body) + 2, *version) + body


def split(data: bytes) -> Iterator[tuple[int, bytes]]:
    """(block type, body after the version bytes) of each block; stops at one that does not fit."""
    off = 0
    while off + 6 <= len(data):
        btype, blen = struct.unpack_from("!HH", data, off)
        if blen < 2 or off + 4 + blen > len(data):
            raise BlockError(0x40, 0x01, f"block {btype:#06x} at {off}: length {blen} beyond the request")
        yield btype, data[off + 6:off + 4 + blen]
        off += 4 + blen


def _need(body: bytes, n: int, btype: int) -> None:
    if len(body) < n:
        raise BlockError(BLOCK_ERROR_CODE1.get(btype, 0x40), 1, f"block {btype:#06x}: {len(body)} bytes, need {n}")


@dataclass(frozen=True)
class ARRequest:
    ar_type: int
    ar_uuid: uuid.UUID
    session_key: int
    initiator_mac: bytes
    initiator_object: uuid.UUID
    properties: int
    timeout_factor: int
    station_name: str


def parse_ar(body: bytes) -> ARRequest:
    _need(body, 52, AR_REQ)
    ar_type, = struct.unpack_from("!H", body, 0)
    ar_uuid = uuid.UUID(bytes=body[2:18])
    session, = struct.unpack_from("!H", body, 18)
    mac = body[20:26]
    obj = uuid.UUID(bytes=body[26:42])
    props, timeout, _udp_port, name_len = struct.unpack_from("!IHHH", body, 42)
    _need(body, 52 + name_len, AR_REQ)
    name = body[52:52 + name_len].decode("ascii", errors="replace")
    if ar_type not in (AR_TYPE_IOCAR, AR_TYPE_IOSAR):
        raise BlockError(0x01, 4, f"AR type {ar_type:#06x}: only IOCARSingle (1) and IOSAR (6)")
    return ARRequest(ar_type, ar_uuid, session, mac, obj, props, timeout, name)


def ar_response(req: ARRequest, mac: bytes, udp_port: int = 0x8892) -> bytes:
    return header(AR_RES, struct.pack("!H", req.ar_type) + req.ar_uuid.bytes
                  + struct.pack("!H", req.session_key) + mac + struct.pack("!H", udp_port))


@dataclass(frozen=True)
class IOObject:
    """A data object (IODataObject: data then IOPS) or an IOCS of one submodule in an IOCR frame."""

    api: int
    slot: int
    subslot: int
    offset: int


@dataclass(frozen=True)
class IOCRRequest:
    iocr_type: int
    reference: int
    lt: int
    properties: int
    data_length: int
    frame_id: int
    send_clock_factor: int
    reduction_ratio: int
    watchdog_factor: int
    data_hold_factor: int
    multicast_mac: bytes
    data: tuple[IOObject, ...]
    iocs: tuple[IOObject, ...]

    @property
    def cycle_s(self) -> float:
        """Cycle time in seconds: SendClockFactor × ReductionRatio × 31.25 µs."""
        return self.send_clock_factor * self.reduction_ratio * 31.25e-6


def parse_iocr(body: bytes) -> IOCRRequest:
    _need(body, 40, IOCR_REQ)
    (typ, ref, lt, props, dlen, fid, scf, rr, _phase, _seq, _fso, wdf, dhf, _tag) = struct.unpack_from(
        "!HHHIHHHHHHIHHH", body, 0)
    mcast = body[32:38]
    n_apis, = struct.unpack_from("!H", body, 38)
    off = 40
    data: list[IOObject] = []
    iocs: list[IOObject] = []
    for _ in range(n_apis):
        _need(body, off + 6, IOCR_REQ)
        api, n = struct.unpack_from("!IH", body, off)
        off += 6
        _need(body, off + 6 * n + 2, IOCR_REQ)
        for i in range(n):
            data.append(IOObject(api, *struct.unpack_from("!HHH", body, off + 6 * i)))
        off += 6 * n
        n, = struct.unpack_from("!H", body, off)
        off += 2
        _need(body, off + 6 * n, IOCR_REQ)
        for i in range(n):
            iocs.append(IOObject(api, *struct.unpack_from("!HHH", body, off + 6 * i)))
        off += 6 * n
    if typ not in (IOCR_INPUT, IOCR_OUTPUT):
        raise BlockError(0x02, 4, f"IOCRType {typ}: only input (1) and output (2)")
    if lt != 0x8892:
        raise BlockError(0x02, 6, f"LT {lt:#06x}: only RT over Ethernet (8892h)")
    if props & 0x0F not in (1, 2):
        raise BlockError(0x02, 7, f"IOCRProperties {props:#x}: only RT_CLASS_1")
    if not 40 <= dlen <= 1440:
        raise BlockError(0x02, 8, f"DataLength {dlen}: 40..1440")
    if scf == 0 or rr == 0 or scf > 128 or rr > 16384:
        raise BlockError(0x02, 10 if scf == 0 or scf > 128 else 11, f"SendClockFactor {scf} / ReductionRatio {rr}")
    if wdf == 0 or dhf == 0 or dhf > 0x1E00 or wdf > 0x1E00:
        raise BlockError(0x02, 15 if wdf == 0 or wdf > 0x1E00 else 16, f"WatchdogFactor {wdf} / DataHoldFactor {dhf}")
    return IOCRRequest(typ, ref, lt, props, dlen, fid, scf, rr, wdf, dhf, mcast, tuple(data), tuple(iocs))


def iocr_response(req: IOCRRequest, frame_id: int) -> bytes:
    return header(IOCR_RES, struct.pack("!HHH", req.iocr_type, req.reference, frame_id))


@dataclass(frozen=True)
class AlarmCRRequest:
    alarm_cr_type: int
    lt: int
    properties: int
    timeout_factor: int
    retries: int
    local_ref: int
    max_data_length: int
    tag_high: int
    tag_low: int


def parse_alarm_cr(body: bytes) -> AlarmCRRequest:
    _need(body, 20, ALARM_CR_REQ)
    req = AlarmCRRequest(*struct.unpack_from("!HHIHHHHHH", body, 0))
    if req.alarm_cr_type != 1:
        raise BlockError(0x03, 4, f"AlarmCRType {req.alarm_cr_type}")
    if req.properties & 0x2:
        raise BlockError(0x03, 6, "alarms over UDP are not supported (AlarmCRProperties.Transport)")
    if not 200 <= req.max_data_length <= 1432:
        raise BlockError(0x03, 11, f"MaxAlarmDataLength {req.max_data_length}: 200..1432")
    return req


def alarm_cr_response(req: AlarmCRRequest, local_ref: int, max_len: int) -> bytes:
    return header(ALARM_CR_RES, struct.pack("!HHH", req.alarm_cr_type, local_ref, max_len))


@dataclass(frozen=True)
class ExpectedSubmodule:
    api: int
    slot: int
    module_ident: int
    subslot: int
    submodule_ident: int
    input_length: int
    output_length: int


def parse_expected(body: bytes) -> list[ExpectedSubmodule]:
    _need(body, 2, EXP_SUBMOD_REQ)
    n_apis, = struct.unpack_from("!H", body, 0)
    off = 2
    out: list[ExpectedSubmodule] = []
    for _ in range(n_apis):
        _need(body, off + 14, EXP_SUBMOD_REQ)
        api, slot, mod_ident, _mprops, n_sub = struct.unpack_from("!IHIHH", body, off)
        off += 14
        for _ in range(n_sub):
            _need(body, off + 8, EXP_SUBMOD_REQ)
            subslot, sub_ident, sprops = struct.unpack_from("!HIH", body, off)
            off += 8
            lengths = {1: 0, 2: 0}
            for _ in range(2 if sprops & 3 == 3 else 1):
                _need(body, off + 6, EXP_SUBMOD_REQ)
                direction, length, _lcs, _lps = struct.unpack_from("!HHBB", body, off)
                off += 6
                if direction in lengths:
                    lengths[direction] = length
            out.append(ExpectedSubmodule(api, slot, mod_ident, subslot, sub_ident, lengths[1], lengths[2]))
    return out


# ModuleState and the IdentInfo field of SubmoduleState (bits 11-14; bit 15: format indicator)
NO_MODULE, WRONG_MODULE, PROPER_MODULE = 0, 1, 2
IDENT_OK, IDENT_WRONG, IDENT_NO_SUBMODULE = 0, 2, 3


@dataclass
class DiffModule:
    slot: int
    module_ident: int
    state: int
    submodules: list[tuple[int, int, int]] = field(default_factory=list)   # subslot, ident, IdentInfo


def module_diff(api: int, modules: list[DiffModule]) -> bytes:
    body = struct.pack("!HIH", 1, api, len(modules))
    for m in modules:
        body += struct.pack("!HIHH", m.slot, m.module_ident, m.state, len(m.submodules))
        for subslot, ident, info in m.submodules:
            body += struct.pack("!HIH", subslot, ident, 0x8000 | info << 11)
    return header(MODULE_DIFF, body)


@dataclass(frozen=True)
class Control:
    block_type: int
    ar_uuid: uuid.UUID
    session_key: int
    command: int


def parse_control(body: bytes, btype: int) -> Control:
    if len(body) < 26:
        raise BlockError(0x40, 1, f"control block {btype:#06x}: {len(body)} bytes, need 26")
    ar_uuid = uuid.UUID(bytes=body[2:18])
    session, _pad, cmd, _props = struct.unpack_from("!HHHH", body, 18)
    return Control(btype, ar_uuid, session, cmd)


def control(block_type: int, ar_uuid: uuid.UUID, session_key: int, command: int) -> bytes:
    return header(block_type, b"\x00\x00" + ar_uuid.bytes + struct.pack("!HHHH", session_key, 0, command, 0))


@dataclass(frozen=True)
class RecordRequest:
    """IODReadReqHeader / IODWriteReqHeader."""

    seq: int
    ar_uuid: uuid.UUID
    api: int
    slot: int
    subslot: int
    index: int
    length: int


def parse_record(body: bytes) -> RecordRequest:
    if len(body) < 34:
        raise BlockError(0x40, 1, f"record header: {len(body)} bytes, need 34")
    seq, = struct.unpack_from("!H", body, 0)
    ar_uuid = uuid.UUID(bytes=body[2:18])
    api, slot, subslot, _pad, index, length = struct.unpack_from("!IHHHHI", body, 18)
    return RecordRequest(seq, ar_uuid, api, slot, subslot, index, length)


def read_response(req: RecordRequest, data: bytes) -> bytes:
    body = (struct.pack("!H", req.seq) + req.ar_uuid.bytes
            + struct.pack("!IHHHHIHH", req.api, req.slot, req.subslot, 0, req.index, len(data), 0, 0) + bytes(20))
    return header(READ_RES, body) + data


def write_response(req: RecordRequest, status: int) -> bytes:
    body = (struct.pack("!H", req.seq) + req.ar_uuid.bytes
            + struct.pack("!IHHHHIHHI", req.api, req.slot, req.subslot, 0, req.index, req.length, 0, 0, status)
            + bytes(16))
    return header(WRITE_RES, body)
