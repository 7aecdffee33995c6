"""Conformance class A without a wire: LLDP frames, the PDEV records of the DAP's interface (8000h) and
port (8001h), identification, ModuleDiff, LogBook and I&M1–4 (IEC 61158-6-10; the I&M guideline), fed
bytes as a controller sends them. The last test has tshark decode every request and answer."""

from __future__ import annotations

import random
import shutil
import struct
import subprocess
from pathlib import Path

import dpkt
import pytest

from pywsg.device import ManualClock, VirtualGripper
from pywsg.fieldbus.controller import FieldbusController
from pywsg.fieldbus.profinet import blocks as b
from pywsg.fieldbus.profinet import lldp, rpc
from pywsg.fieldbus.profinet.ar import ConnectionManager, Identity
from pywsg.fieldbus.profinet.device import ProfinetDevice
from pywsg.fieldbus.profinet.ether import Frame, IpStack, parse_frame
from pywsg.fieldbus.profinet.im import IMData
from pywsg.fieldbus.profinet.station import PermanentStore

from .test_sans_io import MAC, PLC, REAL_EXPECTED, _connect_args, _rpc_request, _station, _status

DEVICE_IP, PLC_IP = "192.168.0.20", "192.168.0.1"


class Clock:
    def __init__(self) -> None:
        self.t = 100.0

    def __call__(self) -> float:
        return self.t


class Session:
    """A connection manager with an IO AR, and every request/answer kept as Ethernet frames (for tshark)."""

    def __init__(self, expected: list[tuple[int, int, int, int, int, int]] = REAL_EXPECTED) -> None:
        self.clock = Clock()
        self.cm = ConnectionManager(_station(), Identity("WSG 50", "10001"))
        self.cm.pdev._clock = self.clock
        self.saved: list[dict[str, object]] = []
        self.cm.im.data.save = self.saved.append
        self.dev, self.plc = IpStack(MAC, DEVICE_IP), IpStack(PLC, PLC_IP)
        self.frames: list[bytes] = []
        status, self.connect_body = self.call(rpc.OP_CONNECT, _connect_args(expected))
        assert status == 0 and self.cm.io_ar is not None
        self.ar = self.cm.io_ar

    def call(self, op: int, args: bytes) -> tuple[int, bytes]:
        req = _rpc_request(op, args, little=True)
        self.frames.append(self.plc.udp(MAC, DEVICE_IP, 0xC001, rpc.RPC_PORT, req))
        reply = self.cm.handle(req, PLC_IP, 0xC001)
        assert reply is not None
        self.frames.append(self.dev.udp(PLC, PLC_IP, rpc.RPC_PORT, 0xC001, reply))
        return _status(reply)

    def read(self, slot: int, subslot: int, index: int) -> tuple[int, bytes]:
        req = b.header(b.READ_REQ, struct.pack("!H", 1) + self.ar.uuid.bytes
                       + struct.pack("!IHHHHI", 0, slot, subslot, 0, index, 4096) + bytes(24))
        status, body = self.call(rpc.OP_READ, req)
        return status, body[64:]

    def write(self, slot: int, subslot: int, index: int, data: bytes) -> int:
        req = b.header(b.WRITE_REQ, struct.pack("!H", 1) + self.ar.uuid.bytes
                       + struct.pack("!IHHHHI", 0, slot, subslot, 0, index, len(data)) + bytes(24)) + data
        return self.call(rpc.OP_WRITE, req)[0]


def _neighbour(name: str = "plc", port: str = "port-001.plc", ttl: int = 20, now: float = 100.0) -> lldp.Neighbour:
    frame = parse_frame(lldp.build(PLC, name, PLC_IP, ttl=ttl).replace(b"port-001." + name.encode(), port.encode()))
    assert frame is not None
    n = lldp.parse(frame, now)
    assert n is not None
    return n


def _pad(data: bytes) -> bytes:
    return data + bytes(-(6 + len(data)) % 4)


def _check(peer_port: str = "port-001", peer_station: str = "plc", mau: int = 0x10, subslot: int = 0x8001,
           peers: int = 1) -> bytes:
    body = bytes([peers]) + (bytes([len(peer_port)]) + peer_port.encode()
                             + bytes([len(peer_station)]) + peer_station.encode()) * peers
    return b.header(0x0200, b"\0\0" + struct.pack("!HH", 0, subslot) + b.header(0x020A, _pad(body))
                    + b.header(0x020C, struct.pack("!H", mau)))


def _adjust(*subs: bytes) -> bytes:
    return b.header(0x0202, b"\0\0" + struct.pack("!HH", 0, 0x8001) + b"".join(subs))


def _boundary(block: int, value: int) -> bytes:
    return b.header(block, b"\0\0" + struct.pack("!IH", value, 0) + b"\0\0")


# --- LLDP ---------------------------------------------------------------------------------------------
def test_lldp_frame_carries_name_port_ttl_and_the_profinet_tlvs() -> None:
    """IEC 61158-6-10 LLDP: chassis ID = NameOfStation, port ID port-001.<name>, TTL 20, PNIO port status
    and chassis MAC, 802.3 MAC/PHY with the GSDML's MAU type, the management address."""
    frame = parse_frame(lldp.build(MAC, "wsg50", DEVICE_IP))
    assert frame is not None and frame.dst == lldp.LLDP_MULTICAST and frame.ethertype == lldp.ETH_P_LLDP
    me = lldp.parse(frame, 0.0)
    assert me is not None
    assert (me.chassis_id, me.port_id, me.ttl) == ("wsg50", "port-001.wsg50", 20)
    assert (me.peer_station_name, me.peer_port_name) == ("wsg50", "port-001")
    assert me.mau_type == 0x10 and me.chassis_mac == MAC and me.management_ip == DEVICE_IP
    assert lldp.OUI_PNIO + bytes([lldp.PNIO_PORT_STATUS]) in frame.payload
    # legacy form (PDInterfaceAdjust NameOfDevice = 0) and an unnamed station (chassis ID = its MAC)
    legacy = lldp.parse(Frame(b"", PLC, lldp.ETH_P_LLDP, lldp.build(MAC, "wsg50", name_of_device=False)[14:]), 0)
    assert legacy is not None and legacy.port_id == "port-001"
    unnamed = lldp.parse(Frame(b"", PLC, lldp.ETH_P_LLDP, lldp.build(MAC, "")[14:]), 0)
    assert unnamed is not None and unnamed.chassis_id == "02:00:00:00:00:01" and not unnamed.management_ip


def test_lldp_bad_frames_are_dropped_and_never_raise() -> None:
    good = lldp.build(PLC, "plc")[14:]
    assert lldp.parse(Frame(b"", PLC, lldp.ETH_P_LLDP, good[:9]), 0) is None          # cut in the port ID
    no_ttl = lldp.tlv(1, b"\x07plc") + lldp.tlv(2, b"\x07port-001") + lldp.tlv(0, b"")
    assert lldp.parse(Frame(b"", PLC, lldp.ETH_P_LLDP, no_ttl), 0) is None             # no TTL TLV
    rnd = random.Random(5)
    for _ in range(3000):
        junk = bytearray(good)
        for _ in range(rnd.randrange(1, 6)):
            junk[rnd.randrange(len(junk))] = rnd.randrange(256)
        lldp.parse(Frame(b"", PLC, lldp.ETH_P_LLDP, bytes(junk[:rnd.randrange(len(junk) + 1)])), 0)


# --- PDEV ---------------------------------------------------------------------------------------------
def test_pd_port_data_real_shows_the_lldp_neighbour_until_its_ttl_runs_out() -> None:
    s = Session()
    status, rec = s.read(0, 0x8001, 0x802A)
    assert status == 0 and rec[:2] == b"\x02\x0f" and rec[21] == 0   # no neighbour yet: NumberOfPeers 0
    s.cm.pdev.port.neighbour = _neighbour()
    status, rec = s.read(0, 0x8001, 0x802A)
    assert status == 0 and rec[21] == 1 and b"\x08port-001\x03plc" in rec and PLC in rec
    s.clock.t += 21   # TTL 20 s
    assert s.read(0, 0x8001, 0x802A)[1][21] == 0
    # at the interface subslot it is no record (invalid index)
    assert s.read(0, 0x8000, 0x802A)[0] == 0xDE80B000


def test_pd_interface_data_real_and_pd_real_data() -> None:
    s = Session()
    status, rec = s.read(0, 0x8000, 0x8080)
    assert status == 0 and rec[:2] == b"\x02\x40" and rec[6:12] == b"\x05wsg50"
    assert MAC in rec and rec[-12:] == bytes([192, 168, 0, 20, 255, 255, 255, 0, 0, 0, 0, 0])
    status, rec = s.read(0, 1, 0xF841)
    kinds = [t for t, _ in b.split(rec)]
    assert status == 0 and kinds == [0x0400, 0x0400]
    inner = [next(b.split(body[10:]))[0] for _t, body in b.split(rec)]
    assert inner == [0x0240, 0x020F]


def test_pd_port_data_check_is_checked_and_compared_with_the_neighbour() -> None:
    s = Session()
    s.cm.pdev.port.neighbour = _neighbour()
    assert s.write(0, 0x8001, 0x802B, _check()) == 0
    assert s.cm.pdev.port.mismatch(s.clock.t) is None
    assert s.read(0, 0x8001, 0x802B)[1] == _check()   # read back as written
    # the controller expects another neighbour: accepted, and the mismatch is known
    assert s.write(0, 0x8001, 0x802B, _check(peer_station="other-plc")) == 0
    assert "expected other-plc/port-001" in str(s.cm.pdev.port.mismatch(s.clock.t))
    # refused: wrong subslot in the block (B2), two peers on one port (B8), a MAU type the port lacks (B7),
    # the record at the interface (B2), a cut block (B8)
    assert s.write(0, 0x8001, 0x802B, _check(subslot=0x8002)) == 0xDF80B200
    assert s.write(0, 0x8001, 0x802B, _check(peers=2)) == 0xDF80B800
    assert s.write(0, 0x8001, 0x802B, _check(mau=0x1E)) == 0xDF80B700
    assert s.write(0, 0x8000, 0x802B, _check()) == 0xDF80B200
    assert s.write(0, 0x8001, 0x802B, _check()[:20]) == 0xDF80B800
    assert s.cm.pdev.port.check.peer_station == "other-plc"   # a refused write changed nothing


def test_pd_port_data_adjust_peer_to_peer_boundary_stops_lldp() -> None:
    s = Session()
    assert s.cm.pdev.port.lldp_send
    assert s.write(0, 0x8001, 0x802F, _adjust(_boundary(0x0209, 1), _boundary(0x0224, 1))) == 0
    assert not s.cm.pdev.port.lldp_send and s.cm.pdev.port.domain_boundary == 1
    assert s.read(0, 0x8001, 0x802F)[1][:2] == b"\x02\x02"
    assert s.write(0, 0x8001, 0x802F, _adjust(_boundary(0x0224, 0))) == 0
    assert s.cm.pdev.port.lldp_send
    mau = b.header(0x020E, b"\0\0" + struct.pack("!HH", 0x1E, 0))
    assert s.write(0, 0x8001, 0x802F, _adjust(mau)) == 0xDF80B700                    # 1000BASE-T: not this port
    assert s.write(0, 0x8001, 0x802F, _adjust(b.header(0x0999, bytes(8)))) == 0xDF80B800   # unknown block
    # PDInterfaceAdjust: the LLDP port ID form
    assert s.write(0, 0x8000, 0x8071, b.header(0x0250, b"\0\0" + struct.pack("!I", 0))) == 0
    assert not s.cm.pdev.port.name_of_device
    assert s.write(0, 0x8000, 0x8071, b.header(0x0250, b"\0\0" + struct.pack("!I", 6))) == 0xDF80B700
    # a PDEV record of a feature the GSDML does not declare (MRP 8052h, NC data check 8070h): invalid index
    assert s.write(0, 0x8000, 0x8052, bytes(8)) == 0xDF80B000
    assert s.write(0, 0x8000, 0x8070, bytes(8)) == 0xDF80B000


def test_identification_module_diff_and_logbook() -> None:
    wrong_port = [*REAL_EXPECTED[:2], (0, 0x8002, 1, 3, 0, 0), REAL_EXPECTED[3]]
    s = Session(wrong_port)
    # the port the controller expects at 8002h does not exist: ModuleDiff says "no submodule"
    diff = dict(b.split(s.connect_body))[b.MODULE_DIFF]
    _sub, _ident, state = struct.unpack_from("!HIH", diff, 18)
    assert _sub == 0x8002 and state >> 11 & 0xF == b.IDENT_NO_SUBMODULE
    status, rec = s.read(0, 1, 0xE002)
    assert status == 0 and rec == b.header(b.MODULE_DIFF, diff)
    # expected vs real of the AR, one slot, one subslot
    _, exp_ar = s.read(0, 1, 0xE000)
    _, real_ar = s.read(0, 1, 0xE001)
    assert struct.pack("!HI", 0x8002, 3) in exp_ar and struct.pack("!HI", 0x8002, 3) not in real_ar
    assert struct.pack("!HI", 0x8001, 3) in real_ar and s.read(0, 1, 0xF000)[1] == real_ar
    _, slot1 = s.read(1, 1, 0xC001)
    assert struct.unpack_from("!HIHHIH", slot1, 6) == (1, 0, 1, 1, 0x10, 1)
    _, sub = s.read(0, 0x8000, 0x8000)
    assert struct.unpack_from("!HI", sub, 22) == (0x8000, 2)
    _, missing = s.read(0, 0x8002, 0x8000)   # expected, not real: its expected data; the real one: no subslot
    assert struct.unpack_from("!HI", missing, 22) == (0x8002, 3) and s.read(0, 0x8002, 0x8001)[0] == 0xDE80B200
    # all proper: an empty ModuleDiff; the LogBook has this AR
    ok = Session()
    assert ok.read(0, 1, 0xE002)[1] == b.header(b.MODULE_DIFF, b"\0\0")
    ok.cm.pdev.logbook.add(ok.ar.uuid.bytes, 0xCF81FD00)
    _, book = ok.read(0, 1, 0xF830)
    assert book[:2] == b"\x00\x19" and struct.unpack_from("!H", book, 14)[0] == 1
    assert ok.ar.uuid.bytes in book and struct.pack("!I", 0xCF81FD00) in book


def test_garbage_record_writes_get_an_answer_and_change_nothing_they_should_not() -> None:
    """3,000 corrupted PDEV and I&M writes: each answered with OK or a PNIORW error, never an exception."""
    s = Session()
    pdev, im_data = s.cm.pdev, s.cm.im
    good = {0x802B: _check(), 0x802F: _adjust(_boundary(0x0209, 1)),
            0x8071: b.header(0x0250, b"\0\0" + struct.pack("!I", 1)),
            0xAFF1: b.header(0x21, b" " * 54), 0xAFF3: b.header(0x23, b" " * 54)}
    where = {0x802B: 0x8001, 0x802F: 0x8001, 0x8071: 0x8000, 0xAFF1: 1, 0xAFF3: 1}
    rnd = random.Random(7)
    codes = set()
    for _ in range(3000):
        index = rnd.choice(list(good))
        data = bytearray(good[index])
        for _ in range(rnd.randrange(1, 4)):
            data[rnd.randrange(len(data))] = rnd.randrange(256)
        data = data[:rnd.randrange(len(data) + 1)] if rnd.random() < 0.3 else data
        req = b.RecordRequest(1, s.ar.uuid, 0, 0, where[index], index, len(data))
        for handler in (pdev, im_data):
            code = handler.write(req, s.ar, bytes(data))
            assert code is None or code in (0, 0xB1, 0xB2, 0xB6, 0xB7, 0xB8)
            codes.add(code)
        assert pdev.read(b.RecordRequest(1, s.ar.uuid, 0, 0, 0x8001, 0x802A, 4096), s.ar, True)
    assert {0, 0xB8} <= codes   # both kinds of answer were exercised


# --- I&M ----------------------------------------------------------------------------------------------
def test_im0_says_im1_to_im4_are_there_and_the_filter_lists_the_dap() -> None:
    s = Session()
    _, im0 = s.read(0, 1, 0xAFF0)
    assert struct.unpack_from("!H", im0, len(im0) - 2)[0] == 0b11110   # IM_Supported: I&M1..I&M4
    assert im0[8:28].rstrip() == b"WSG 50"
    _, filt = s.read(0, 1, 0xF840)
    assert [t for t, _ in b.split(filt)] == [0x0030, 0x0031, 0x0032]
    for _t, body in b.split(filt):
        assert struct.unpack_from("!HIHHIHHI", body) == (1, 0, 1, 0, 1, 1, 1, 1)


def test_im1_to_im4_write_read_and_refusals() -> None:
    s = Session()
    assert s.read(0, 1, 0xAFF1)[1] == b.header(0x21, b" " * 54)   # blank until written
    assert s.read(0, 1, 0xAFF4)[1] == b.header(0x24, bytes(54))
    im1 = b.header(0x21, b"left gripper".ljust(32) + b"cell 7".ljust(22))
    assert s.write(0, 1, 0xAFF1, im1) == 0 and s.read(0, 1, 0xAFF1)[1] == im1
    assert s.read(1, 1, 0xAFF1)[1] == im1   # slot 1 is represented by the DAP (I&M0FilterData)
    assert s.write(0, 1, 0xAFF2, b.header(0x22, b"2026-11-28 05:00")) == 0
    assert s.write(0, 1, 0xAFF3, b.header(0x23, b"spare".ljust(54))) == 0
    assert s.write(0, 1, 0xAFF4, b.header(0x24, bytes(range(54)))) == 0
    assert s.saved == [{"im1_tag_function": "left gripper", "im1_tag_location": "cell 7"},
                       {"im2_date": "2026-11-28 05:00"}, {"im3_descriptor": "spare"},
                       {"im4_signature": bytes(range(54)).hex()}]
    # refusals leave the record as it was
    assert s.write(0, 1, 0xAFF1, im1[:-1]) == 0xDF80B100                                  # length
    assert s.write(0, 1, 0xAFF2, b.header(0x22, b"2026-13-28 05:00")) == 0xDF80B700      # no 13th month
    assert s.write(0, 1, 0xAFF3, b.header(0x23, b"\x01" * 54)) == 0xDF80B800              # not visible
    assert s.write(0, 1, 0xAFF1, b.header(0x22, bytes(54))) == 0xDF80B800                 # wrong block
    assert s.write(0, 1, 0xAFF0, bytes(60)) == 0xDF80B600                                 # I&M0: read only
    assert s.read(0, 1, 0xAFF1)[1] == im1 and len(s.saved) == 4


def test_im_values_survive_a_restart_in_the_settings_file(tmp_path: Path) -> None:
    path = tmp_path / "settings.interface.json"
    store = PermanentStore(path)
    store.save(profinet_name="wsg50")
    data = IMData.load(store.data, save=lambda changed: store.save(**changed))
    assert data.write(0xAFF1, b.header(0x21, b"left".ljust(32) + b"cell 7".ljust(22))) == 0
    assert data.write(0xAFF4, b.header(0x24, b"\x5a" * 54)) == 0
    again = IMData.load(PermanentStore(path).data)   # a new process reads the file
    assert again.record(0xAFF1) == data.record(0xAFF1) and again.record(0xAFF4)[6:] == b"\x5a" * 54
    assert PermanentStore(path).name() == "wsg50"   # the other keys stay
    # the web interface's Command Interface page writes the same file: the I&M keys stay
    from pywsg.web.interface_page import InterfaceStore

    assert InterfaceStore(path).update({"profinet_name": "wsg-renamed"}) == {}
    kept = IMData.load(PermanentStore(path).data)
    assert kept.record(0xAFF1) == data.record(0xAFF1) and PermanentStore(path).name() == "wsg-renamed"
    bad = IMData.load({"im1_tag_function": "x" * 40, "im4_signature": "zz"})
    assert bad.record(0xAFF1) == b.header(0x21, b" " * 54) and bad.record(0xAFF4)[6:] == bytes(54)


# --- the device: I&M from the settings file, the neighbour in the Fieldbus Monitor -------------------------
def test_device_reads_im_from_the_settings_file_and_shows_the_neighbour(tmp_path: Path) -> None:
    """A ProfinetDevice made on ``lo`` (nothing is opened before start()): what a restart finds in the
    settings file, and the Fieldbus Monitor's LLDP and port-check rows."""
    path = tmp_path / "settings.interface.json"
    PermanentStore(path).save(im1_tag_function="left gripper", im1_tag_location="cell 7")
    gripper = VirtualGripper("wsg50", clock=ManualClock())
    dev = ProfinetDevice(gripper, "lo", FieldbusController(gripper), station_name="wsg50",
                         store=PermanentStore(path))
    assert dev.cm.im.data.record(0xAFF1) == b.header(0x21, b"left gripper".ljust(32) + b"cell 7".ljust(22))
    assert dev.cm.im.data.write(0xAFF3, b.header(0x23, b"spare".ljust(54))) == 0
    assert PermanentStore(path).data["im3_descriptor"] == "spare"   # written through to the file
    assert dev.bus_state()["LLDP neighbour"] == "(none)"
    dev._frame(lldp.build(PLC, "plc", PLC_IP))   # as the raw socket hands it over
    assert dev.bus_state()["LLDP neighbour"] == "plc port-001 (02:00:00:00:00:02)"
    dev.port.check.peer_port, dev.port.check.peer_station = "port-002", "plc"
    assert dev.bus_state()["Port check"] == "mismatch: neighbour plc/port-001, expected plc/port-002"
    # the device's own frame: its name, the port ID form a PDInterfaceAdjust chose
    dev.port.name_of_device = False
    own = lldp.parse(Frame(b"", MAC, lldp.ETH_P_LLDP, dev._lldp_frame()[14:]), 0)
    assert own is not None and (own.chassis_id, own.port_id) == ("wsg50", "port-001")


# --- the whole exchange through tshark ---------------------------------------------------------------
@pytest.mark.skipif(shutil.which("tshark") is None, reason="tshark is not installed (scripts/test.sh installs it)")
def test_tshark_decodes_lldp_pdev_and_im_without_malformed(tmp_path: Path) -> None:
    s = Session()
    s.cm.pdev.port.neighbour = _neighbour()
    s.frames.append(lldp.build(MAC, "wsg50", DEVICE_IP))
    for slot, sub, index in [(0, 0x8001, 0x802A), (0, 0x8000, 0x8080), (0, 1, 0xF841), (0, 1, 0xAFF0),
                             (0, 1, 0xAFF1), (0, 1, 0xAFF2), (0, 1, 0xAFF3), (0, 1, 0xAFF4), (0, 1, 0xF840),
                             (0, 1, 0x8000), (0, 1, 0x8001), (1, 1, 0xC000), (1, 1, 0xC001), (0, 1, 0xE000),
                             (0, 1, 0xE001), (0, 1, 0xF000), (0, 1, 0xE002), (0, 1, 0xF830)]:
        assert s.read(slot, sub, index)[0] == 0
    assert s.write(0, 1, 0xAFF1, b.header(0x21, b"left".ljust(32) + b"cell 7".ljust(22))) == 0
    assert s.write(0, 0x8001, 0x802B, _check()) == 0
    assert s.write(0, 0x8001, 0x802F, _adjust(_boundary(0x0209, 1))) == 0
    assert s.write(0, 0x8000, 0x8071, b.header(0x0250, b"\0\0" + struct.pack("!I", 1))) == 0
    for index in (0x802B, 0x802F):
        assert s.read(0, 0x8001, index)[0] == 0
    path = tmp_path / "pdev.pcap"
    with path.open("wb") as f:
        w = dpkt.pcap.Writer(f)
        for i, frame in enumerate(s.frames):
            w.writepkt(frame, ts=1000 + i / 100)
    r = subprocess.run(["tshark", "-r", str(path), "-T", "fields", "-e", "frame.protocols", "-e", "_ws.malformed",
                        "-e", "_ws.expert.severity", "-e", "pn_io.block_type"], capture_output=True, text=True,
                       timeout=60)
    assert r.returncode == 0, r.stderr
    rows = [line.split("\t") for line in r.stdout.splitlines()]
    assert len(rows) == len(s.frames)
    flagged = [row for row in rows if row[1] or any(int(x, 0) >= 0x00800000 for x in row[2].split(",") if x)]
    assert flagged == []
    assert sum("lldp" in row[0] for row in rows) == 1
    blocks = {int(x, 0) for row in rows for x in row[3].split(",") if x}
    # every record block decoded by name: PDPortDataReal ... LogBookData
    assert {0x020F, 0x0240, 0x0400, 0x0020, 0x0021, 0x0022, 0x0023, 0x0024, 0x0030, 0x0032, 0x0012, 0x0013,
            0x8104, 0x0019, 0x0200, 0x020A, 0x0202, 0x0250, 0x0031} <= blocks
