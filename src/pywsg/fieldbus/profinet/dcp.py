"""PROFINET DCP (Discovery and basic Configuration Protocol), device side, sans-IO.

Identify (all, or filtered by NameOfStation, TypeOfStation, DeviceID, DeviceRole or IP), Get and Set
of NameOfStation and the IP suite (BlockQualifier bit 0: 1 permanent, 0 temporary), Signal (flash
once) and Reset to factory (IEC 61158-6-10 §4.3; frame IDs FEFEh/FEFFh/FEFDh, EtherType 8892h).
Every length field is checked against the frame before it is used: a bad frame is dropped.
"""

from __future__ import annotations

import logging
import struct
from collections.abc import Callable
from dataclasses import dataclass

from .ether import ETH_P_PNIO, Frame, ether
from .refusals import RefusalLog
from .station import IpSuite, Station, ip_suite_error, name_error

log = logging.getLogger(__name__)

IDENTIFY_MULTICAST = bytes.fromhex("010ecf000000")
FID_HELLO, FID_GET_SET, FID_IDENTIFY_REQ, FID_IDENTIFY_RES = 0xFEFC, 0xFEFD, 0xFEFE, 0xFEFF
SID_GET, SID_SET, SID_IDENTIFY = 3, 4, 5
REQUEST, RESPONSE_SUCCESS, RESPONSE_UNSUPPORTED = 0, 1, 5

OPT_IP, OPT_DEVICE, OPT_DHCP, OPT_CONTROL, OPT_ALL = 1, 2, 3, 5, 0xFF
IP_MAC, IP_PARAMETER = (1, 1), (1, 2)
DEV_TYPE, DEV_NAME, DEV_ID, DEV_ROLE, DEV_OPTIONS, DEV_ALIAS, DEV_INSTANCE = (
    (2, 1), (2, 2), (2, 3), (2, 4), (2, 5), (2, 6), (2, 7))
CTRL_START, CTRL_STOP, CTRL_SIGNAL, CTRL_RESPONSE, CTRL_RESET_FACTORY, CTRL_RESET_TO_FACTORY = (
    (5, 1), (5, 2), (5, 3), (5, 4), (5, 5), (5, 6))
ALL_SELECTOR = (0xFF, 0xFF)

# BlockError of a Control/Response block
OK, OPTION_UNSUPPORTED, SUBOPTION_UNSUPPORTED, SUBOPTION_NOT_SET, RESOURCE_ERROR, SET_NOT_POSSIBLE, \
    IN_OPERATION = range(7)

SUPPORTED = (IP_MAC, IP_PARAMETER, DEV_TYPE, DEV_NAME, DEV_ID, DEV_ROLE, DEV_OPTIONS, DEV_INSTANCE,
             CTRL_START, CTRL_STOP, CTRL_SIGNAL, CTRL_RESPONSE, CTRL_RESET_FACTORY, CTRL_RESET_TO_FACTORY)
ROLE_IO_DEVICE = 0x01
#: ResetToFactory modes (BlockQualifier bits 1-15): 2 = reset communication parameters (NameOfStation, IP
#: suite, temporary and permanent), the one the GSDML declares (ResetToFactoryModes); others are refused.
RESET_COMMUNICATION = 2
RESET_MODES = (RESET_COMMUNICATION,)
#: Spacing of the identify response delay (IEC 61158-6-10: 10 ms × (address mod ResponseDelayFactor)).
DELAY_UNIT_S = 0.010
MAX_BLOCKS = 64   # more blocks than any real request carries: the rest of a flood frame is ignored


@dataclass
class DcpHandlers:
    """What a DCP Set does to the device; each returns a BlockError (``OK`` = 0 on success)."""

    set_name: Callable[[str, bool], int]
    set_ip: Callable[[IpSuite, bool], int]
    signal: Callable[[], None]
    reset: Callable[[int], int]


def _blocks(data: bytes) -> list[tuple[int, int, bytes]]:
    """(option, suboption, value) of each block; stops at the first one that does not fit."""
    out: list[tuple[int, int, bytes]] = []
    off = 0
    while off + 4 <= len(data) and len(out) < MAX_BLOCKS:
        opt, sub, length = struct.unpack_from("!BBH", data, off)
        if off + 4 + length > len(data):
            break
        out.append((opt, sub, data[off + 4:off + 4 + length]))
        off += 4 + length + (length & 1)
    return out


def _block(option: tuple[int, int], value: bytes) -> bytes:
    raw = struct.pack("!BBH", option[0], option[1], len(value)) + value
    return raw + (b"\x00" if len(value) & 1 else b"")


class DcpResponder:
    """Answers DCP requests for one :class:`Station`. :meth:`handle` returns (delay s, frame) pairs."""

    def __init__(self, station: Station, handlers: DcpHandlers) -> None:
        self.station = station
        self.handlers = handlers
        self.requests = 0   # DCP requests answered (for the Fieldbus Monitor)
        self.refusals = RefusalLog(log)

    def handle(self, frame: Frame) -> list[tuple[float, bytes]]:
        if frame.ethertype != ETH_P_PNIO or len(frame.payload) < 12:
            return []
        fid, sid, stype, xid, delay, length = struct.unpack_from("!HBBIHH", frame.payload)
        if stype != REQUEST or length > len(frame.payload) - 12:
            return []
        blocks = _blocks(frame.payload[12:12 + length])
        if fid == FID_IDENTIFY_REQ and sid == SID_IDENTIFY and frame.dst in (IDENTIFY_MULTICAST, self.station.mac):
            return self._identify(frame.src, xid, delay, blocks)
        if fid == FID_GET_SET and frame.dst == self.station.mac:
            if sid == SID_GET:
                body = self._get(frame.payload[12:12 + length])
                return [(0.0, self._reply(frame.src, FID_GET_SET, SID_GET, xid, body))]
            if sid == SID_SET:
                return [(0.0, self._reply(frame.src, FID_GET_SET, SID_SET, xid, self._set(blocks)))]
        return []

    # --- identify ---------------------------------------------------------------------------------
    def _identify(self, dst: bytes, xid: int, delay_factor: int, blocks: list[tuple[int, int, bytes]]) -> list[
            tuple[float, bytes]]:
        if not blocks:
            return []
        for opt, sub, value in blocks:
            if not self._matches((opt, sub), value):
                return []
        body = b"".join(self._value_block(o) for o in (DEV_OPTIONS, DEV_TYPE, DEV_NAME, DEV_ID, DEV_ROLE,
                                                       DEV_INSTANCE, IP_PARAMETER))
        self.requests += 1
        # 0 and 1 mean "answer at once"; else spread answers by the low bits of the MAC — except for an
        # Identify by NameOfStation, which one device answers at most (docs/fidelity.md).
        by_name = any((o, s) == DEV_NAME for o, s, _ in blocks)
        spread = int.from_bytes(self.station.mac[4:], "big") % delay_factor if delay_factor > 1 and not by_name else 0
        delay = DELAY_UNIT_S * spread
        return [(delay, self._reply(dst, FID_IDENTIFY_RES, SID_IDENTIFY, xid, body))]

    def _matches(self, option: tuple[int, int], value: bytes) -> bool:
        st = self.station
        if option == ALL_SELECTOR:
            return True
        if option == DEV_NAME:
            # valid names are lowercase (IEC 61158-6-10 NameOfStation): compared as they are, so "WSG50"
            # is another name than "wsg50", not a spelling of it
            return value == st.name.encode() and st.name != ""
        if option == DEV_TYPE:
            return value == st.type_of_station.encode()
        if option == DEV_ID:
            return value == struct.pack("!HH", st.vendor_id, st.device_id)
        if option == DEV_ROLE:
            return len(value) >= 1 and bool(value[0] & ROLE_IO_DEVICE)
        if option == IP_PARAMETER:
            return value[:12] == st.ip.raw()
        if option == DEV_INSTANCE:
            return value == b"\x00\x01"
        return False   # a filter we do not know: not us

    def _value_block(self, option: tuple[int, int]) -> bytes:
        """A response block: BlockInfo (2 bytes) + value."""
        st = self.station
        if option == DEV_OPTIONS:
            value = b"".join(bytes(o) for o in SUPPORTED)
        elif option == DEV_TYPE:
            value = st.type_of_station.encode()
        elif option == DEV_NAME:
            value = st.name.encode()
        elif option == DEV_ID:
            value = struct.pack("!HH", st.vendor_id, st.device_id)
        elif option == DEV_ROLE:
            value = bytes([ROLE_IO_DEVICE, 0])
        elif option == DEV_INSTANCE:
            value = b"\x00\x01"
        elif option == IP_PARAMETER:
            info = 0 if st.ip.ip == "0.0.0.0" else 1   # nosec B104; BlockInfo bit 0: IP set
            return _block(option, struct.pack("!H", info) + st.ip.raw())
        elif option == IP_MAC:
            value = st.mac
        else:
            raise KeyError(option)
        return _block(option, b"\x00\x00" + value)

    # --- get / set --------------------------------------------------------------------------------
    def _get(self, data: bytes) -> bytes:
        out = []
        for i in range(0, min(len(data) & ~1, 2 * MAX_BLOCKS), 2):
            option = (data[i], data[i + 1])
            if option in (DEV_OPTIONS, DEV_TYPE, DEV_NAME, DEV_ID, DEV_ROLE, DEV_INSTANCE, IP_PARAMETER, IP_MAC):
                out.append(self._value_block(option))
            else:
                out.append(self._response(option, OPTION_UNSUPPORTED if option[0] not in (1, 2, 5)
                                          else SUBOPTION_UNSUPPORTED))
        self.requests += 1
        return b"".join(out)

    def _set(self, blocks: list[tuple[int, int, bytes]]) -> bytes:
        out = []
        for opt, sub, value in blocks:
            option = (opt, sub)
            error = self._set_one(option, value)
            out.append(self._response(option, error))
        self.requests += 1
        return b"".join(out)

    def _set_one(self, option: tuple[int, int], value: bytes) -> int:
        if len(value) < 2:
            return SUBOPTION_NOT_SET
        qualifier = int.from_bytes(value[:2], "big")
        data = value[2:]
        permanent = bool(qualifier & 1)
        if option == DEV_NAME:
            try:
                name = data.decode("ascii")
            except UnicodeDecodeError:
                return SUBOPTION_NOT_SET
            if name_error(name) is not None:
                self.refusals.warn("DCP Set NameOfStation %r refused: %s", name, name_error(name))
                return SUBOPTION_NOT_SET
            return self.handlers.set_name(name, permanent)
        if option == IP_PARAMETER:
            if len(data) != 12:
                return SUBOPTION_NOT_SET
            suite = IpSuite.from_raw(data)
            problem = ip_suite_error(suite.ip, suite.mask, suite.gateway)
            if problem is not None:
                self.refusals.warn("DCP Set IP refused: %s", problem)
                return SUBOPTION_NOT_SET
            return self.handlers.set_ip(suite, permanent)
        if option == CTRL_SIGNAL:
            self.handlers.signal()
            return OK
        if option in (CTRL_START, CTRL_STOP):
            return OK
        if option == CTRL_RESET_FACTORY:   # the older FactoryReset suboption: the communication parameters
            return self.handlers.reset(RESET_COMMUNICATION)
        if option == CTRL_RESET_TO_FACTORY:
            mode = qualifier >> 1
            if mode not in RESET_MODES:
                self.refusals.warn("DCP Reset to Factory mode %d refused: only mode(s) %s", mode,
                                   ", ".join(str(m) for m in RESET_MODES))
                return SUBOPTION_UNSUPPORTED
            return self.handlers.reset(mode)
        return OPTION_UNSUPPORTED if option[0] not in (1, 2, 3, 5) else SUBOPTION_UNSUPPORTED

    @staticmethod
    def _response(option: tuple[int, int], error: int) -> bytes:
        return _block(CTRL_RESPONSE, bytes([option[0], option[1], error]))

    def _reply(self, dst: bytes, fid: int, sid: int, xid: int, body: bytes) -> bytes:
        header = struct.pack("!HBBIHH", fid, sid, RESPONSE_SUCCESS, xid, 0, len(body))
        return ether(dst, self.station.mac, ETH_P_PNIO, header + body)
