"""The physical device (PDEV) records of the DAP's interface (subslot 8000h) and port (8001h), the
identification records and the LogBook (IEC 61158-6-10 "PDEV", "Identification", "LogBook"), sans-IO.

Read (all blocks big endian, padded to 4 bytes from the block start where the standard pads):

==========  ========================  =======================================================
index       record                    what it holds here
==========  ========================  =======================================================
802Ah       PDPortDataReal (020Fh)    own port name, the LLDP neighbour (peer port and station
                                      name, its MAC), MAU type, boundaries, link state, media
802Bh       PDPortDataCheck (0200h)   what the controller last wrote (empty until then)
802Fh       PDPortDataAdjust (0202h)  what the controller last wrote (empty until then)
8071h       PDInterfaceAdjust (0250h) MultipleInterfaceMode (LLDP port ID form)
8080h       PDInterfaceDataReal       NameOfStation as chassis ID, MAC, IP suite
            (0240h)
F841h       PDRealData                both of the above, each in a MultipleBlockHeader (0400h)
8000h/C000h ExpectedIdentification    the AR's expected submodules of one subslot / slot / the AR
/E000h      Data (0012h)
8001h/C001h RealIdentificationData    the real submodules of one subslot / slot / the AR / API 0
/E001h/     (0013h)
F000h
E002h       ModuleDiffBlock (8104h)   the AR's differences (no API when there are none)
F830h       LogBookData (0019h)       the last :data:`LOGBOOK_SIZE` AR events with PNIOStatus
==========  ========================  =======================================================

Written and checked (a refused write answers PNIORW ErrorCode1 B8h "invalid parameter", B7h "invalid
range" or B2h "invalid slot/subslot"): PDPortDataCheck (CheckPeers, CheckLineDelay, CheckMAUType,
CheckLinkState, CheckMAUTypeDifference), PDPortDataAdjust (domain, multicast, peer-to-peer and DCP
boundaries, MAU type, link state, preamble length), PDInterfaceAdjust. A CheckPeers that does not match
the LLDP neighbour is kept and shown as a mismatch (Fieldbus Monitor, log); a PeerToPeerBoundary with
bit 0 set stops the LLDP frames, as the standard says.
"""

from __future__ import annotations

import ipaddress
import logging
import struct
import time
from collections import deque
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Protocol

from . import blocks as b
from .lldp import MAU_100BASE_TXFD, PORT_NAME, Neighbour

if TYPE_CHECKING:
    from .station import Station

log = logging.getLogger(__name__)

API = 0
INTERFACE, PORT = (0, 0x8000), (0, 0x8001)
PD_PORT_DATA_REAL, PD_PORT_DATA_CHECK, PD_PORT_DATA_ADJUST = 0x802A, 0x802B, 0x802F
PD_INTERFACE_ADJUST, PD_INTERFACE_DATA_REAL, PD_REAL_DATA = 0x8071, 0x8080, 0xF841
EXPECTED_SUBSLOT, REAL_SUBSLOT, EXPECTED_SLOT, REAL_SLOT = 0x8000, 0x8001, 0xC000, 0xC001
EXPECTED_AR, REAL_AR, MODULE_DIFF_AR, REAL_API, LOGBOOK = 0xE000, 0xE001, 0xE002, 0xF000, 0xF830

BLOCK_PORT_DATA_REAL, BLOCK_PORT_DATA_CHECK, BLOCK_PORT_DATA_ADJUST = 0x020F, 0x0200, 0x0202
BLOCK_INTERFACE_DATA_REAL, BLOCK_INTERFACE_ADJUST, BLOCK_MULTIPLE = 0x0240, 0x0250, 0x0400
BLOCK_EXPECTED_IDENT, BLOCK_REAL_IDENT, BLOCK_LOGBOOK = 0x0012, 0x0013, 0x0019
CHECK_PEERS, CHECK_LINE_DELAY, CHECK_MAU_TYPE, CHECK_LINK_STATE, CHECK_SYNC_MODE, CHECK_MAU_DIFF = (
    0x020A, 0x020B, 0x020C, 0x021C, 0x021D, 0x021E)
ADJUST_DOMAIN, ADJUST_MULTICAST, ADJUST_MAU_TYPE, ADJUST_LINK_STATE = 0x0209, 0x0210, 0x020E, 0x021B
ADJUST_PEER_TO_PEER, ADJUST_DCP, ADJUST_PREAMBLE = 0x0224, 0x0225, 0x0226

INVALID_SLOT, INVALID_RANGE, INVALID_PARAMETER = 0xB2, 0xB7, 0xB8
#: LinkState: Port "forwarding" (5) in the high byte, Link "up" (1) in the low one.
LINK_UP_FORWARDING = 0x0501
MEDIA_COPPER = 1
LOGBOOK_SIZE = 16
MAX_NAME = 240


def _pad4(data: bytes, start: int = 6) -> bytes:
    """``data`` padded with zeros so that ``start + len`` is a multiple of 4 (``start``: where it begins
    in its block; the body of a block starts after its 6-byte header)."""
    return data + bytes(-(start + len(data)) % 4)


def _name(text: str) -> bytes:
    raw = text.encode("ascii", errors="replace")[:MAX_NAME]
    return bytes([len(raw)]) + raw


class RealSubmodule(Protocol):
    """A submodule of the real configuration (:data:`pywsg.fieldbus.profinet.ar.REAL`)."""

    @property
    def slot(self) -> int: ...
    @property
    def subslot(self) -> int: ...
    @property
    def module_ident(self) -> int: ...
    @property
    def submodule_ident(self) -> int: ...


class ARView(Protocol):
    """What these records need of an AR (:class:`pywsg.fieldbus.profinet.ar.AR`)."""

    @property
    def expected(self) -> Mapping[tuple[int, int], b.ExpectedSubmodule]: ...
    @property
    def diff(self) -> bytes: ...


@dataclass
class PortCheck:
    """What the controller's PDPortDataCheck asks of the port (None: not checked)."""

    peer_port: str | None = None
    peer_station: str | None = None
    mau_type: int | None = None
    raw: bytes = b""


@dataclass
class Port:
    """State of the device's one port: the LLDP neighbour and what the controller adjusted/checks."""

    neighbour: Neighbour | None = None
    check: PortCheck = field(default_factory=PortCheck)
    adjust_raw: bytes = b""
    interface_adjust_raw: bytes = b""
    domain_boundary: int = 0
    multicast_boundary: int = 0
    peer_to_peer_boundary: int = 0
    #: MultipleInterfaceMode.NameOfDevice: True = LLDP port ID ``port-001.<NameOfStation>``.
    name_of_device: bool = True

    @property
    def lldp_send(self) -> bool:
        """PeerToPeerBoundary bit 0: "the LLDP agent shall not send LLDP frames"."""
        return not self.peer_to_peer_boundary & 1

    def current(self, now: float) -> Neighbour | None:
        """The neighbour while its TTL lasts."""
        n = self.neighbour
        return n if n is not None and n.alive(now) else None

    def mismatch(self, now: float) -> str | None:
        """Why the neighbour is not the one PDPortDataCheck expects, or None (also when nothing is checked)."""
        c = self.check
        if c.peer_port is None:
            return None
        n = self.current(now)
        if n is None:
            return f"no LLDP neighbour (expected {c.peer_station}/{c.peer_port})"
        if (n.peer_station_name, n.peer_port_name) != (c.peer_station, c.peer_port):
            return f"neighbour {n.peer_station_name}/{n.peer_port_name}, expected {c.peer_station}/{c.peer_port}"
        return None


@dataclass(frozen=True)
class LogEntry:
    time_us: int
    ar_uuid: bytes
    pnio_status: int
    detail: int


class LogBook:
    """The last AR events (LogBookData, F830h); times in µs since the device started."""

    def __init__(self, clock: object = time.monotonic) -> None:
        self._clock = clock if callable(clock) else time.monotonic
        self._start = self._clock()
        self.entries: deque[LogEntry] = deque(maxlen=LOGBOOK_SIZE)

    def now_us(self) -> int:
        return int((self._clock() - self._start) * 1e6)

    def add(self, ar_uuid: bytes, pnio_status: int = 0, detail: int = 0) -> None:
        self.entries.append(LogEntry(self.now_us(), ar_uuid, pnio_status, detail))

    def record(self) -> bytes:
        body = struct.pack("!QH", self.now_us(), len(self.entries))
        for e in self.entries:
            body += struct.pack("!Q", e.time_us) + e.ar_uuid + struct.pack("!II", e.pnio_status, e.detail)
        return b.header(BLOCK_LOGBOOK, body)


def identification(block_type: int, subs: list[tuple[int, int, int, int, int]]) -> bytes:
    """Expected/RealIdentificationData, block version 1.1: (api, slot, module, subslot, submodule) rows
    grouped per API and slot."""
    apis: dict[int, dict[int, list[tuple[int, int, int]]]] = {}
    for api, slot, module, subslot, submodule in subs:
        apis.setdefault(api, {}).setdefault(slot, []).append((module, subslot, submodule))
    body = struct.pack("!H", len(apis))
    for api, slots in sorted(apis.items()):
        body += struct.pack("!IH", api, len(slots))
        for slot, rows in sorted(slots.items()):
            body += struct.pack("!HIH", slot, rows[0][0], len(rows))
            body += b"".join(struct.pack("!HI", subslot, submodule) for _m, subslot, submodule in rows)
    return b.header(block_type, body, (1, 1))


class PDevRecords:
    """PDEV, identification and LogBook records: a record handler of the connection manager."""

    def __init__(self, station: Station, real: Sequence[RealSubmodule], port: Port | None = None,
                 logbook: LogBook | None = None, clock: object = time.monotonic) -> None:
        self.station = station
        self.real = real
        self.port = port or Port()
        self.logbook = logbook or LogBook(clock)
        self._clock = clock if callable(clock) else time.monotonic

    # --- read -------------------------------------------------------------------------------------
    def port_data_real(self) -> bytes:
        n = self.port.current(self._clock())
        body = b"\x00\x00" + struct.pack("!HH", *PORT) + _name(PORT_NAME)
        body = _pad4(body + bytes([1 if n else 0]))
        if n is not None:
            peer = _pad4(body + _name(n.peer_port_name) + _name(n.peer_station_name))
            body = _pad4(peer + struct.pack("!I", 0) + n.mac)
        body = _pad4(body + struct.pack("!H", MAU_100BASE_TXFD))
        body = _pad4(body + struct.pack("!IIH", self.port.domain_boundary, self.port.multicast_boundary,
                                        LINK_UP_FORWARDING))
        return b.header(BLOCK_PORT_DATA_REAL, body + struct.pack("!I", MEDIA_COPPER))

    def interface_data_real(self) -> bytes:
        s = self.station
        body = _pad4(_name(s.name))
        body = _pad4(body + s.mac)
        body += b"".join(ipaddress.IPv4Address(x).packed for x in (s.ip.ip, s.ip.mask, s.ip.gateway))
        return b.header(BLOCK_INTERFACE_DATA_REAL, body)

    @staticmethod
    def _multiple(subslot: tuple[int, int], inner: bytes) -> bytes:
        return b.header(BLOCK_MULTIPLE, b"\x00\x00" + struct.pack("!IHH", API, *subslot) + inner)

    def real_data(self) -> bytes:
        """PDRealData (F841h): the interface's and the port's real data."""
        return (self._multiple(INTERFACE, self.interface_data_real())
                + self._multiple(PORT, self.port_data_real()))

    def _ident(self, index: int, req: b.RecordRequest, ar: ARView | None) -> bytes | None:
        def keep(slot: int, subslot: int) -> bool:
            if index in (EXPECTED_SUBSLOT, REAL_SUBSLOT):
                return (slot, subslot) == (req.slot, req.subslot)
            if index in (EXPECTED_SLOT, REAL_SLOT):
                return slot == req.slot
            return True

        if index in (EXPECTED_SUBSLOT, EXPECTED_SLOT, EXPECTED_AR):
            if ar is None:
                return None
            rows = [(e.api, e.slot, e.module_ident, e.subslot, e.submodule_ident) for e in ar.expected.values()
                    if keep(e.slot, e.subslot)]
            return identification(BLOCK_EXPECTED_IDENT, rows)
        rows = [(API, s.slot, s.module_ident, s.subslot, s.submodule_ident) for s in self.real
                if keep(s.slot, s.subslot)]
        return identification(BLOCK_REAL_IDENT, rows)

    def read(self, req: b.RecordRequest, ar: ARView | None, real: bool) -> bytes | None:
        """The record, or None when the index is not one of these (or not at this address)."""
        at = (req.slot, req.subslot)
        index = req.index
        # what the AR expects is readable also where nothing real is (that is what a controller asks about)
        if index in (EXPECTED_AR, REAL_AR, REAL_API, EXPECTED_SUBSLOT, EXPECTED_SLOT) or (
                real and index in (REAL_SUBSLOT, REAL_SLOT)):
            return self._ident(index, req, ar)
        if index == MODULE_DIFF_AR:
            if ar is None:
                return None
            return ar.diff or b.header(b.MODULE_DIFF, struct.pack("!H", 0))
        if index == LOGBOOK:
            return self.logbook.record()
        if index == PD_REAL_DATA:
            return self.real_data()
        if at == PORT:
            return {PD_PORT_DATA_REAL: self.port_data_real, PD_PORT_DATA_CHECK: lambda: self.port.check.raw,
                    PD_PORT_DATA_ADJUST: lambda: self.port.adjust_raw}.get(index, lambda: None)()
        if at == INTERFACE:
            if index == PD_INTERFACE_DATA_REAL:
                return self.interface_data_real()
            if index == PD_INTERFACE_ADJUST:
                return self.port.interface_adjust_raw
        return None

    # --- write ------------------------------------------------------------------------------------
    def write(self, req: b.RecordRequest, ar: ARView | None, data: bytes) -> int | None:
        """0, a PNIORW ErrorCode1, or None when the index is not a PDEV record."""
        writers = {PD_PORT_DATA_CHECK: (PORT, self._check), PD_PORT_DATA_ADJUST: (PORT, self._adjust),
                   PD_INTERFACE_ADJUST: (INTERFACE, self._interface_adjust)}
        if req.index not in writers:
            return None
        where, apply = writers[req.index]
        if (req.slot, req.subslot) != where:
            return INVALID_SLOT
        return apply(data)

    @staticmethod
    def _outer(data: bytes, block_type: int) -> tuple[int, bytes] | int:
        """(0, the sub-blocks) of a PDPortDataCheck/Adjust block for the port, or an ErrorCode1."""
        body = _only_block(data, block_type)
        if body is None:
            return INVALID_PARAMETER
        if struct.unpack_from("!HH", body, 2) != PORT:
            return INVALID_SLOT
        return 0, body[6:]

    def _check(self, data: bytes) -> int:
        outer = self._outer(data, BLOCK_PORT_DATA_CHECK)
        if isinstance(outer, int):
            return outer
        check = PortCheck(raw=data)
        subs = _blocks(outer[1])
        if not subs:
            return INVALID_PARAMETER
        for btype, body in subs:
            if btype == CHECK_PEERS:
                peers = _peers(body)
                if peers is None or len(peers) != 1:   # one port, one neighbour: exactly one peer
                    return INVALID_PARAMETER
                check.peer_port, check.peer_station = peers[0]
            elif btype == CHECK_MAU_TYPE:
                if len(body) < 2:
                    return INVALID_PARAMETER
                check.mau_type, = struct.unpack_from("!H", body)
                if check.mau_type != MAU_100BASE_TXFD:
                    return INVALID_RANGE   # the port has only the GSDML's MAU type
            elif btype not in (CHECK_LINE_DELAY, CHECK_LINK_STATE, CHECK_MAU_DIFF):
                return INVALID_PARAMETER   # CheckSyncMode and unknown blocks: not for an RT_CLASS_1 port
        self.port.check = check
        why = self.port.mismatch(self._clock())
        if why is not None:
            log.warning("PROFINET: PDPortDataCheck: %s", why)
        return 0

    def _adjust(self, data: bytes) -> int:
        outer = self._outer(data, BLOCK_PORT_DATA_ADJUST)
        if isinstance(outer, int):
            return outer
        subs = _blocks(outer[1])
        if subs is None:
            return INVALID_PARAMETER
        values: dict[int, int] = {}
        for btype, body in subs:
            if btype in (ADJUST_DOMAIN, ADJUST_MULTICAST, ADJUST_PEER_TO_PEER, ADJUST_DCP):
                if len(body) < 8:
                    return INVALID_PARAMETER
                values[btype], = struct.unpack_from("!I", body, 2)
            elif btype in (ADJUST_MAU_TYPE, ADJUST_LINK_STATE, ADJUST_PREAMBLE):
                if len(body) < 6:
                    return INVALID_PARAMETER
                value, = struct.unpack_from("!H", body, 2)
                if btype == ADJUST_MAU_TYPE and value != MAU_100BASE_TXFD:
                    return INVALID_RANGE
                if btype == ADJUST_PREAMBLE and value > 1:
                    return INVALID_RANGE
            else:
                return INVALID_PARAMETER
        p = self.port
        p.domain_boundary = values.get(ADJUST_DOMAIN, 0)
        p.multicast_boundary = values.get(ADJUST_MULTICAST, 0)
        p.peer_to_peer_boundary = values.get(ADJUST_PEER_TO_PEER, 0)
        p.adjust_raw = data
        return 0

    def _interface_adjust(self, data: bytes) -> int:
        body = _only_block(data, BLOCK_INTERFACE_ADJUST)
        if body is None:
            return INVALID_PARAMETER
        mode, = struct.unpack_from("!I", body, 2)
        if mode & ~1:
            return INVALID_RANGE   # only bit 0 (NameOfDevice) is defined
        self.port.name_of_device = bool(mode & 1)
        self.port.interface_adjust_raw = data
        return 0


def _blocks(data: bytes) -> list[tuple[int, bytes]] | None:
    """The blocks of ``data``, or None when one runs past its end."""
    try:
        return list(b.split(data))
    except b.BlockError:
        return None


def _only_block(data: bytes, block_type: int) -> bytes | None:
    """The body of ``data`` when it is exactly one block of ``block_type`` with padding and at least 4 bytes
    after it (slot/subslot or a 32-bit value), else None."""
    found = _blocks(data)
    if found is None or len(found) != 1 or found[0][0] != block_type or len(found[0][1]) < 6:
        return None
    return found[0][1]


def _peers(body: bytes) -> list[tuple[str, str]] | None:
    """CheckPeers: NumberOfPeers, then per peer LengthPeerPortName, PeerPortName, LengthPeerStationName,
    PeerStationName; None when a length runs past the block or a name is empty."""
    if not body:
        return None
    n, off, out = body[0], 1, []
    for _ in range(n):
        names = []
        for _part in range(2):
            if off >= len(body):
                return None
            length = body[off]
            raw = body[off + 1:off + 1 + length]
            if length == 0 or len(raw) != length:
                return None
            names.append(raw.decode("ascii", errors="replace"))
            off += 1 + length
        out.append((names[0], names[1]))
    return out
