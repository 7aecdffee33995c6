"""The PROFINET device's protocol layers without a wire (no root needed): DCP, DCE/RPC, the connection
manager, the RT frame codec and the alarm channel, fed bytes as a controller would send them
(IEC 61158-6-10; the module layout: 002 §3.1 / 003 §4.1)."""

from __future__ import annotations

import random
import struct
import uuid

import pytest

from pywsg.fieldbus.profinet import blocks as b
from pywsg.fieldbus.profinet import rpc
from pywsg.fieldbus.profinet.alarm import AlarmChannel
from pywsg.fieldbus.profinet.ar import REAL, ConnectionManager, Identity, Listener
from pywsg.fieldbus.profinet.dcp import DcpHandlers, DcpResponder
from pywsg.fieldbus.profinet.ether import Frame, IpStack, parse_frame
from pywsg.fieldbus.profinet.rt import CyclicCodec
from pywsg.fieldbus.profinet.station import IpSuite, Station, name_error, parse_ip_suite
from pywsg.protocol import SystemFlag

MAC = bytes.fromhex("020000000001")
PLC = bytes.fromhex("020000000002")
MCAST = bytes.fromhex("010ecf000000")


def _station() -> Station:
    return Station(mac=MAC, name="wsg50", ip=IpSuite("192.168.0.20", "255.255.255.0", "0.0.0.0"))


def _dcp(station: Station, sets: list[tuple[str, object, bool]] | None = None) -> DcpResponder:
    log = sets if sets is not None else []

    def set_name(n: str, p: bool) -> int:
        log.append(("name", n, p))
        station.name = n
        return 0

    def set_ip(s: IpSuite, p: bool) -> int:
        log.append(("ip", s.ip, p))
        return 0

    return DcpResponder(station, DcpHandlers(set_name, set_ip, lambda: log.append(("signal", None, False)),
                                             lambda mode: 0))


def _dcp_frame(dst: bytes, fid: int, sid: int, blocks: bytes, delay: int = 1) -> Frame:
    return Frame(dst, PLC, 0x8892, struct.pack("!HBBIHH", fid, sid, 0, 0x1234, delay, len(blocks)) + blocks)


def _blocks_of(reply: bytes) -> dict[tuple[int, int], bytes]:
    f = parse_frame(reply)
    assert f is not None
    length = int.from_bytes(f.payload[10:12], "big")
    data, out, off = f.payload[12:12 + length], {}, 0
    while off + 4 <= len(data):
        o, s, n = struct.unpack_from("!BBH", data, off)
        out[(o, s)] = data[off + 4:off + 4 + n]
        off += 4 + n + (n & 1)
    return out


def test_dcp_identify_all_and_by_name() -> None:
    st = _station()
    dcp = _dcp(st)
    [(delay, reply)] = dcp.handle(_dcp_frame(MCAST, 0xFEFE, 5, b"\xff\xff\x00\x00", delay=0x80))
    assert 0 <= delay < 1.28
    blocks = _blocks_of(reply)
    assert blocks[(2, 2)][2:] == b"wsg50" and blocks[(2, 3)][2:] == bytes.fromhex("02a20001")
    assert blocks[(1, 2)] == b"\x00\x01" + st.ip.raw()
    # by name: answered at once; another name: silence
    [(delay, _)] = dcp.handle(_dcp_frame(MCAST, 0xFEFE, 5, b"\x02\x02\x00\x05wsg50\x00", delay=0x80))
    assert delay == 0
    assert dcp.handle(_dcp_frame(MCAST, 0xFEFE, 5, b"\x02\x02\x00\x05other\x00")) == []


def test_dcp_set_name_permanent_and_bad_names_refused() -> None:
    st = _station()
    sets: list[tuple[str, object, bool]] = []
    dcp = _dcp(st, sets)
    [(_, reply)] = dcp.handle(_dcp_frame(MAC, 0xFEFD, 4, b"\x02\x02\x00\x0a\x00\x01new-name"))
    assert _blocks_of(reply)[(5, 4)] == b"\x02\x02\x00" and sets == [("name", "new-name", True)]
    [(_, reply)] = dcp.handle(_dcp_frame(MAC, 0xFEFD, 4, b"\x02\x02\x00\x06\x00\x00Bad_N\x00"))
    assert _blocks_of(reply)[(5, 4)] == b"\x02\x02\x03"   # BlockError 3: not set
    assert name_error("port-001") and name_error("1.2.3.4") and name_error("") is None


def test_dcp_garbage_never_raises() -> None:
    dcp = _dcp(_station())
    rnd = random.Random(3)
    for _ in range(3000):
        fid = rnd.choice([0xFEFE, 0xFEFD, 0xFEFC, rnd.randrange(65536)])
        body = struct.pack("!H", fid) + bytes(rnd.randrange(256) for _ in range(rnd.randrange(0, 64)))
        for reply in dcp.handle(Frame(rnd.choice([MAC, MCAST]), PLC, 0x8892, body)):
            assert len(reply[1]) >= 60


def test_ip_suite_text() -> None:
    assert parse_ip_suite("192.168.0.20/24,192.168.0.1") == IpSuite("192.168.0.20", "255.255.255.0", "192.168.0.1")
    with pytest.raises(ValueError):
        parse_ip_suite("192.168.0.20/24,10.0.0.1")   # gateway outside the subnet


def _connect_args(expected: list[tuple[int, int, int, int, int, int]], scf: int = 32, rr: int = 8) -> bytes:
    ar = (struct.pack("!H", 1) + uuid.uuid4().bytes + struct.pack("!H", 7) + PLC + uuid.uuid4().bytes
          + struct.pack("!IHHH", 0x11, 100, 0x8892, 3) + b"plc")
    ios: list[bytes] = []
    for typ in (1, 2):
        objs = b""
        iocs = b""
        off = 0
        for slot, sub, _m, _s, inp, outp in expected:
            length = inp if typ == 1 else outp
            if length or (typ == 1 and not outp):
                objs += struct.pack("!HHH", slot, sub, off)
                off += length + 1
        n_objs = len(objs) // 6
        for slot, sub, _m, _s, inp, outp in expected:
            if (outp if typ == 1 else (inp or not outp)):
                iocs += struct.pack("!HHH", slot, sub, off)
                off += 1
        body = (struct.pack("!HHHIHHHHHHIHHH", typ, typ, 0x8892, 1, max(40, off), 0xFFFF if typ == 2 else 0xC001,
                            scf, rr, 1, 0, 0xFFFFFFFF, 3, 3, 0xC000) + bytes(6) + struct.pack("!H", 1)
                + struct.pack("!IH", 0, n_objs) + objs + struct.pack("!H", len(iocs) // 6) + iocs)
        ios.append(b.header(b.IOCR_REQ, body))
    alarm = b.header(b.ALARM_CR_REQ, struct.pack("!HHIHHHHHH", 1, 0x8892, 0, 1, 3, 1, 200, 0xC000, 0xA000))
    exp = struct.pack("!H", len(expected))
    for slot, sub, mod, sid, inp, outp in expected:
        typ = 3 if inp and outp else 1 if inp else 2 if outp else 0
        dds = struct.pack("!HHBB", 1, inp, 1, 1) if typ in (0, 1, 3) else b""
        dds += struct.pack("!HHBB", 2, outp, 1, 1) if typ in (2, 3) else b""
        exp += struct.pack("!IHIHH", 0, slot, mod, 0, 1) + struct.pack("!HIH", sub, sid, typ) + dds
    return b.header(b.AR_REQ, ar) + ios[0] + ios[1] + alarm + b.header(b.EXP_SUBMOD_REQ, exp)


def _rpc_request(op: int, args: bytes, little: bool = False) -> bytes:
    hdr = rpc.RpcHeader(rpc.REQUEST, 0x20, 0, b"\x10\x00\x00" if little else b"\x00\x00\x00", uuid.uuid4(),
                        rpc.UUID_DEVICE, uuid.uuid4(), 0, 1, 0, op, 0, 0, 0)
    return rpc.build(hdr, rpc.ndr_request(args, little))


def _status(reply: bytes) -> tuple[int, bytes]:
    parsed = rpc.parse(reply)
    assert parsed is not None
    hdr, body = parsed
    assert hdr.ptype == rpc.RESPONSE and hdr.little   # the device answers little endian
    status, n = struct.unpack_from("<II", body)
    return status, body[20:20 + n]


REAL_EXPECTED = [(s.slot, s.subslot, s.module_ident, s.submodule_ident, s.input_length, s.output_length)
                 for s in REAL]


@pytest.mark.parametrize("little", [False, True])
def test_connect_read_im0_and_a_second_controller(little: bool) -> None:
    cm = ConnectionManager(_station(), Identity("WSG 50", "10001"))
    status, body = _status(cm.handle(_rpc_request(rpc.OP_CONNECT, _connect_args(REAL_EXPECTED), little), "x", 1))
    assert status == 0 and cm.io_ar is not None
    kinds = [t for t, _ in b.split(body)]
    assert kinds == [b.AR_RES, b.IOCR_RES, b.IOCR_RES, b.ALARM_CR_RES]   # no ModuleDiff: all proper
    # I&M0 (AFF0h) of slot 0 / subslot 1 in this AR
    read = (b.header(b.READ_REQ, struct.pack("!H", 1) + cm.io_ar.uuid.bytes
                     + struct.pack("!IHHHHI", 0, 0, 1, 0, 0xAFF0, 4096) + bytes(24)))
    status, body = _status(cm.handle(_rpc_request(rpc.OP_READ, read, little), "x", 1))
    assert status == 0 and body[64:66] == b"\x00\x20" and body[70:72] == b"\x02\xa2"
    assert body[72:92].rstrip() == b"WSG 50"
    # an unknown index: DE 80 B0 00 (PNIORW, invalid index)
    bad = read[:-30] + struct.pack("!HI", 0xBEEF, 4096) + bytes(24)
    status, _ = _status(cm.handle(_rpc_request(rpc.OP_READ, bad, little), "x", 1))
    assert status == 0xDE80B000
    # a second controller: DB 81 40 04, the first AR untouched
    first = cm.io_ar
    status, _ = _status(cm.handle(_rpc_request(rpc.OP_CONNECT, _connect_args(REAL_EXPECTED), little), "y", 2))
    assert status == 0xDB814004 and cm.io_ar is first


def test_wrong_expected_submodule_gets_a_module_diff_and_bad_iops() -> None:
    wrong = [*REAL_EXPECTED[:3], (1, 1, 0x10, 0x99, 12, 8)]
    cm = ConnectionManager(_station(), Identity("WSG 50", "1"))
    status, body = _status(cm.handle(_rpc_request(rpc.OP_CONNECT, _connect_args(wrong)), "x", 1))
    assert status == 0
    blocks = dict(b.split(body))
    diff = blocks[b.MODULE_DIFF]
    assert struct.unpack_from("!HIH", diff) == (1, 0, 1)                  # one API, one module
    slot, _ident, state, n = struct.unpack_from("!HIHH", diff, 8)
    assert (slot, state, n) == (1, b.PROPER_MODULE, 1)
    _sub, real_ident, sstate = struct.unpack_from("!HIH", diff, 18)
    assert real_ident == 0x11 and sstate >> 11 & 0xF == b.IDENT_WRONG
    assert cm.io_ar is not None
    codec = CyclicCodec(cm.io_ar, MAC)
    codec.provider_ok = True
    frame = codec.input_frame(bytes(range(12)))
    assert bytes(range(12)) not in frame   # the wrong submodule's data is not sent
    # DataStatus: 35h; StationProblemIndicator 0 (15h) while a diagnosis is pending (IEC 61158-6-10)
    c_sdu_end = 18 + 2 + cm.io_ar.input_cr.data_length   # type: ignore[union-attr]
    assert frame[c_sdu_end + 2] == 0x35
    codec.station_problem = True
    assert codec.input_frame(bytes(12))[c_sdu_end + 2] == 0x15


def test_cycle_shorter_than_the_device_interval_is_refused() -> None:
    cm = ConnectionManager(_station(), Identity("WSG 50", "1"))
    status, _ = _status(cm.handle(_rpc_request(rpc.OP_CONNECT, _connect_args(REAL_EXPECTED, rr=1)), "x", 1))
    assert status == 0xDB81020B and cm.io_ar is None   # 1 ms < MinDeviceInterval 64 (2 ms)
    status, _ = _status(cm.handle(_rpc_request(rpc.OP_CONNECT, _connect_args(REAL_EXPECTED, rr=2)), "x", 1))
    assert status == 0 and cm.io_ar is not None


def test_malformed_rpc_never_raises_and_retransmissions_get_the_same_answer() -> None:
    cm = ConnectionManager(_station(), Identity("WSG 50", "1"), Listener())
    rnd = random.Random(5)
    good = _rpc_request(rpc.OP_CONNECT, _connect_args(REAL_EXPECTED))
    for _ in range(2000):
        data = bytearray(good)
        for _ in range(rnd.randrange(1, 6)):
            data[rnd.randrange(len(data))] = rnd.randrange(256)
        cut = bytes(data[:rnd.randrange(len(data) + 1)]) if rnd.random() < 0.3 else bytes(data)
        cm.handle(cut, "x", 1)
        cm.io_ar = None
    first = cm.handle(good, "x", 1)
    assert first is not None and cm.handle(good, "x", 1) == first   # same activity + sequence: cached answer


def test_rt_output_frame_goes_through_only_when_valid() -> None:
    cm = ConnectionManager(_station(), Identity("WSG 50", "1"))
    cm.handle(_rpc_request(rpc.OP_CONNECT, _connect_args(REAL_EXPECTED)), "x", 1)
    ar = cm.io_ar
    assert ar is not None and ar.output_cr is not None
    codec = CyclicCodec(ar, MAC)
    out_obj = next(o for o in ar.output_cr.data if (o.slot, o.subslot) == (1, 1))
    c = bytearray(ar.output_cr.data_length)
    c[out_obj.offset:out_obj.offset + 8] = b"\x08\x00\x00\x00\x00\x00\x00\x00"
    c[out_obj.offset + 8] = 0x80   # IOPS good
    frame = struct.pack("!H", ar.output_frame_id) + bytes(c) + struct.pack("!HBB", 32, 0x35, 0)
    got = codec.output(frame)
    assert got is not None and got.outputs == b"\x08" + bytes(7)
    stopped = frame[:-4] + struct.pack("!HBB", 64, 0x25, 0)   # ProviderState STOP
    got = codec.output(stopped)
    assert got is not None and got.outputs is None
    assert codec.output(frame[:20]) is None


def test_alarm_channel_sends_appears_and_disappears_and_retransmits() -> None:
    cm = ConnectionManager(_station(), Identity("WSG 50", "1"))
    cm.handle(_rpc_request(rpc.OP_CONNECT, _connect_args(REAL_EXPECTED)), "x", 1)
    assert cm.io_ar is not None
    ch = AlarmChannel(cm.io_ar, MAC, cm.alarm_ref)
    ch.flags(int(SystemFlag.SF_FAST_STOP))
    [first] = ch.poll(0.0)
    assert ch.poll(0.05) == [] and ch.poll(0.2) == [first]     # retransmitted after RTATimeoutFactor × 100 ms
    seq = struct.unpack_from("!H", first, 26)[0]   # after dst, src, 802.1Q tag, EtherType, FrameID, refs, type
    ack = struct.pack("!HHBBHHH", cm.alarm_ref, 1, 0x13, 0x01, 0xFFFE, seq, 0)
    ch.handle(ack)
    assert ch.pending is None and ch.acked == 1
    ch.flags(0)
    [second] = ch.poll(1.0)
    assert struct.unpack_from("!H", second, 26)[0] == (seq + 1) & 0x7FFF

    def specifier(frame: bytes) -> int:   # ChannelProperties.Specifier of the one ChannelDiagnosis item
        pdu = frame[32:32 + struct.unpack_from("!H", frame, 30)[0]]
        return int(struct.unpack_from("!H", pdu, len(pdu) - 4)[0] >> 11 & 3)

    assert (specifier(first), specifier(second)) == (1, 2)   # appears, then disappears


def test_ip_stack_answers_arp_only_for_its_address() -> None:
    st = IpStack(MAC, "192.168.0.20")
    arp = (b"\xff" * 6 + PLC + b"\x08\x06" + bytes.fromhex("0001080006040001") + PLC + bytes([192, 168, 0, 1])
           + bytes(6) + bytes([192, 168, 0, 20]))
    f = parse_frame(arp)
    assert f is not None
    replies, udp = st.handle(f)
    assert len(replies) == 1 and udp is None and replies[0][:6] == PLC
    other = arp[:-1] + b"\x15"
    f = parse_frame(other)
    assert f is not None and st.handle(f) == ([], None)


def test_disappears_alarms_say_whether_other_faults_remain() -> None:
    """IEC 61158-6-10: a fault that goes while others stay is a Diagnosis alarm with Specifier 3
    ("disappears, other remain"); the last one to go is AlarmType 000Ch "Diagnosis disappears", Specifier 2
    (002 §3.3's listed flags)."""
    cm = ConnectionManager(_station(), Identity("WSG 50", "1"))
    cm.handle(_rpc_request(rpc.OP_CONNECT, _connect_args(REAL_EXPECTED)), "x", 1)
    assert cm.io_ar is not None
    ch = AlarmChannel(cm.io_ar, MAC, cm.alarm_ref)
    SF = SystemFlag

    def drained() -> list[tuple[int, int, int, bool]]:   # AlarmType, ChannelErrorType, Specifier, faults remain
        out = []
        while ch.queue:
            pdu = ch.queue.popleft()
            alarm_type, = struct.unpack_from("!H", pdu, 6)
            spec, = struct.unpack_from("!H", pdu, 24)
            _ch, props, error = struct.unpack_from("!HHH", pdu, 28)
            out.append((alarm_type, error, props >> 11 & 3, bool(spec & 0x2000)))
        return out

    ch.flags(int(SF.SF_FAST_STOP | SF.SF_TEMP_FAULT))
    assert drained() == [(1, 0x010C, 1, True), (1, 0x0005, 1, True)]
    ch.flags(int(SF.SF_FAST_STOP))
    assert drained() == [(1, 0x0005, 3, True)]
    ch.flags(0)
    assert drained() == [(0x000C, 0x010C, 2, False)]
    ch.flags(int(SF.SF_CURR_FAULT | SF.SF_POWER_FAULT))
    drained()
    ch.flags(0)   # both go at once: the first "other remain", the last "disappears"
    assert [(t, s) for t, _e, s, _r in drained()] == [(1, 3), (0x000C, 2)]
