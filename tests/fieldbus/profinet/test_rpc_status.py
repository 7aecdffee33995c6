"""PNIO RPC answers as a controller and Wireshark read them (issue 31 items 5-9; IEC 61158-6-10 PNIOStatus,
IODReadRes/IODWriteResHeader, diagnosis records), sans-IO: requests a controller sends (good and refused)
go through the connection manager; each answer is checked field by field, and the whole exchange is written
to a pcap that tshark must decode without a Malformed frame or Error-level expert info."""

from __future__ import annotations

import struct
import uuid
from pathlib import Path

import pytest

from pywsg.fieldbus.profinet import blocks as b
from pywsg.fieldbus.profinet import rpc
from pywsg.fieldbus.profinet.ar import ConnectionManager, Identity
from pywsg.fieldbus.profinet.ether import IpStack, mac_text
from pywsg.protocol import SystemFlag

from .test_sans_io import MAC, PLC, REAL_EXPECTED, _connect_args, _rpc_request, _station
from .tshark import counts, flagged, needs_tshark, write_pcap

DEV_IP, PLC_IP = "192.168.0.20", "192.168.0.1"


class Session:
    """A connection manager and the frames of every request and answer, for the pcap."""

    def __init__(self) -> None:
        self.cm = ConnectionManager(_station(), Identity("WSG 50", "10001"))
        self.flags = 0
        self.cm.sysstate = lambda: self.flags
        self.plc, self.dev = IpStack(PLC, PLC_IP), IpStack(MAC, DEV_IP)
        self.frames: list[bytes] = []

    def send(self, data: bytes) -> tuple[rpc.RpcHeader, int, bytes]:
        """Header, PNIOStatus and NDR args of the device's answer to ``data``."""
        self.frames.append(self.plc.udp(MAC, DEV_IP, 0xC002, rpc.RPC_PORT, data))
        reply = self.cm.handle(data, PLC_IP, 0xC002)
        assert reply is not None
        self.frames.append(self.dev.udp(PLC, PLC_IP, rpc.RPC_PORT, 0xC002, reply))
        parsed = rpc.parse(reply)
        assert parsed is not None
        hdr, body = parsed
        status, n = struct.unpack_from("<II", body)
        return hdr, status, body[20:20 + n]

    def call(self, op: int, args: bytes) -> tuple[int, bytes]:
        _hdr, status, out = self.send(_rpc_request(op, args))
        return status, out


def record_req(btype: int, ar: uuid.UUID, slot: int, subslot: int, index: int, length: int) -> bytes:
    return b.header(btype, struct.pack("!H", 1) + ar.bytes + struct.pack("!IHHHHI", 0, slot, subslot, 0, index, length)
                    + bytes(24))


def control_req(btype: int, ar: uuid.UUID, session: int, cmd: int) -> bytes:
    return b.control(btype, ar, session, cmd)


@pytest.fixture(scope="module")
def session() -> Session:
    s = Session()
    status, _ = s.call(rpc.OP_CONNECT, _connect_args(REAL_EXPECTED))
    assert status == 0 and s.cm.io_ar is not None
    return s


def test_error_code_per_operation(session: Session) -> None:
    """An unusable request (its NDR header lies) is refused with the operation's own ErrorCode: Connect DB,
    Release DC, Read DE, Write DF, Control DD, ReadImplicit DE (before: DB + opnum, 4 of 6 wrong)."""
    want = {rpc.OP_CONNECT: 0xDB, rpc.OP_RELEASE: 0xDC, rpc.OP_READ: 0xDE, rpc.OP_WRITE: 0xDF,
            rpc.OP_CONTROL: 0xDD, rpc.OP_READ_IMPLICIT: 0xDE}
    for op, code in want.items():
        hdr = rpc.RpcHeader(rpc.REQUEST, 0x20, 0, b"\x00\x00\x00", uuid.uuid4(), rpc.UUID_DEVICE, uuid.uuid4(), 0, 1,
                            0, op, 0, 0, 0)
        bad_ndr = struct.pack(">IIIII", 4096, 50, 4096, 0, 50) + bytes(10)   # ArgsLength beyond the body
        _h, status, args = session.send(rpc.build(hdr, bad_ndr))
        assert status >> 24 == code and status & 0xFFFFFF == 0x814000, (op, hex(status))
        # a Write is answered with an IODWriteResHeader even so; the others with no blocks
        assert [t for t, _ in b.split(args)] == ([b.WRITE_RES] if op == rpc.OP_WRITE else [])
    ar = session.cm.io_ar
    assert ar is not None
    # refused Control and Release: an AR UUID nobody has (DD / DC 81 40 05)
    status, _ = session.call(rpc.OP_CONTROL, control_req(b.PRM_END_REQ, uuid.uuid4(), 1, b.CMD_PRM_END))
    assert status == 0xDD814005
    status, _ = session.call(rpc.OP_RELEASE, control_req(b.RELEASE_REQ, uuid.uuid4(), 1, b.CMD_RELEASE))
    assert status == 0xDC814005
    assert session.cm.io_ar is ar


def test_a_refused_write_carries_its_iod_write_res_header(session: Session) -> None:
    ar = session.cm.io_ar
    assert ar is not None
    for slot, index, length, data, want in ((1, 0xBEEF, 4, b"abcd", 0xDF80B000),      # invalid index
                                            (9, 0x0001, 4, b"abcd", 0xDF80B200),      # invalid slot
                                            (1, 0x0001, 8, b"abcd", 0xDF80B100)):     # data shorter than said
        status, out = session.call(rpc.OP_WRITE, record_req(b.WRITE_REQ, ar.uuid, slot, 1, index, length) + data)
        assert status == want, hex(status)
        [(btype, body)] = list(b.split(out))
        assert btype == b.WRITE_RES and struct.unpack_from("!H", body, 28)[0] == index
        assert struct.unpack_from("!I", body, 38)[0] == want   # the header's own PNIOStatus
    status, out = session.call(rpc.OP_WRITE, record_req(b.WRITE_REQ, uuid.uuid4(), 1, 1, 1, 4) + b"abcd")
    assert status == 0xDF814005 and [t for t, _ in b.split(out)] == [b.WRITE_RES]


def test_a_read_shorter_than_the_record_is_refused_whole(session: Session) -> None:
    """I&M0 is 60 bytes; RecordDataLength 10 gets DE 80 B7 (access, invalid range) and no data — never a
    block whose BlockLength says 56 where 10 bytes follow."""
    ar = session.cm.io_ar
    assert ar is not None
    status, out = session.call(rpc.OP_READ, record_req(b.READ_REQ, ar.uuid, 0, 1, 0xAFF0, 10))
    assert status == 0xDE80B700 and out == b""
    status, out = session.call(rpc.OP_READ, record_req(b.READ_REQ, ar.uuid, 0, 1, 0xAFF0, 60))
    assert status == 0 and len(out) == 64 + 60
    status, _ = session.call(rpc.OP_READ, record_req(b.READ_REQ, ar.uuid, 0, 1, 0xBEEF, 4096))
    assert status == 0xDE80B000


def test_diagnosis_records_carry_the_active_channel_diagnosis(session: Session) -> None:
    """800Ah/C00Ah/E00Ah/F00Ah (and the B/C variants, F80Ch): the WSG submodule's DiagnosisData block with one
    ChannelDiagnosis item per listed 002 §3.3 flag set; empty when none is."""
    ar = session.cm.io_ar
    assert ar is not None
    session.flags = int(SystemFlag.SF_FAST_STOP | SystemFlag.SF_TEMP_FAULT | SystemFlag.SF_MOVING)
    for index, slot, subslot in ((0x800A, 1, 1), (0x800B, 1, 1), (0x800C, 1, 1), (0xC00A, 1, 1), (0xE00A, 0, 1),
                                 (0xE00C, 0, 1), (0xF00A, 0, 1), (0xF80C, 0, 1)):
        status, out = session.call(rpc.OP_READ, record_req(b.READ_REQ, ar.uuid, slot, subslot, index, 4096))
        assert status == 0, (hex(index), hex(status))
        data = out[64:]
        btype, blen, vh, vl, api, s, ss, ch, _props, usi = struct.unpack_from("!HHBBIHHHHH", data)
        assert (btype, vh, vl, api, s, ss, ch, usi) == (0x0010, 1, 1, 0, 1, 1, 0x8000, 0x8000), hex(index)
        items = [struct.unpack_from("!HHH", data, 20 + 6 * i) for i in range((blen + 4 - 20) // 6)]
        assert [(c, p >> 11 & 3, t) for c, p, t in items] == [(0x8000, 1, 0x010C), (0x8000, 1, 0x0005)], hex(index)
    # another slot's or subslot's record holds nothing; no listed flag set: every record is empty
    status, out = session.call(rpc.OP_READ, record_req(b.READ_REQ, ar.uuid, 0, 1, 0x800A, 4096))
    assert status == 0 and out[64:] == b""
    session.flags = int(SystemFlag.SF_MOVING)
    status, out = session.call(rpc.OP_READ, record_req(b.READ_REQ, ar.uuid, 1, 1, 0x800A, 4096))
    assert status == 0 and out[64:] == b""
    status, _ = session.call(rpc.OP_READ, record_req(b.READ_REQ, ar.uuid, 7, 1, 0x800A, 4096))
    assert status == 0xDE80B200   # no such slot


@needs_tshark
def test_wireshark_finds_every_answer_clean(session: Session, tmp_path: Path) -> None:
    """Every answer in this module's session (the refusals above; its own when it runs alone), decoded by
    tshark, has no Malformed frame and no Error-level expert info (the device's frames; some requests are
    malformed on purpose)."""
    ar = session.cm.io_ar
    assert ar is not None
    status, _ = session.call(rpc.OP_CONTROL, control_req(b.PRM_END_REQ, ar.uuid, ar.request.session_key,
                                                         b.CMD_PRM_END))
    assert status == 0
    status, _ = session.call(rpc.OP_READ_IMPLICIT, record_req(b.READ_REQ, uuid.UUID(int=0), 0, 1, 0xAFF0, 4096))
    assert status == 0
    for index in (0xBEEF, 0xBEF0, 0xBEF1, 0xBEF2):   # refused writes (also when this test runs alone)
        status, _ = session.call(rpc.OP_WRITE, record_req(b.WRITE_REQ, ar.uuid, 1, 1, index, 4) + b"abcd")
        assert status == 0xDF80B000
    status, _ = session.call(rpc.OP_READ, record_req(b.READ_REQ, ar.uuid, 0, 1, 0xAFF0, 10))   # too short
    assert status == 0xDE80B700
    pcap = write_pcap(tmp_path / "rpc.pcap", session.frames)
    assert flagged(pcap, mac_text(MAC)) == []
    answers = counts(pcap, f"eth.src == {mac_text(MAC)} && pn_io.error_code")
    assert answers == len(session.frames) // 2, answers   # tshark read every answer as PNIO
    assert counts(pcap, "pn_io.block_type == 0x8008") >= 4       # the refused writes' IODWriteResHeader
