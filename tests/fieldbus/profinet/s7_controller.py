"""An IO controller that starts up the way an S7 PLC does, written frame by frame on raw sockets
(``struct`` only: nothing of pywsg's PROFINET code, so it checks the device independently). Run inside the
controller namespace:

    python s7_controller.py IFACE startup STATION IP      # the whole startup, one JSON line
    python s7_controller.py IFACE im STATION IP           # DCP Set IP by name, then an implicit read of I&M1

``startup``: DCP Identify by NameOfStation and Set IP (temporary) to the MAC it answered from; LLDP out (as
the PLC's port does) and the device's LLDP in; Connect with the DAP (subslot 1), its interface (8000h) and
port (8001h) submodules and the WSG module; the cyclic output frames from then on; PDEV writes in one
WriteMultiple (PDPortDataCheck, PDPortDataAdjust, PDInterfaceAdjust) and I&M1; reads of PDPortDataReal,
PDRealData and I&M0; PrmEnd; the device's ApplicationReady answered; cyclic data (HOMING); a diagnosis
alarm (FASTSTOP) acknowledged on both RTA levels, and its end; JOG with the provider in RUN, then
DataStatus ProviderState STOP (the image still says JOG) and back to RUN; Release.

The register image (8 output / 12 input bytes) is the manuals' (002 §3.1, 003 §4.1): pywsg.fieldbus.image.
"""

from __future__ import annotations

import json
import queue
import socket
import struct
import sys
import threading
import time
import uuid
from dataclasses import dataclass, field
from typing import Any

from pywsg.fieldbus.image import CmdFlag, InputImage, OutputImage

ETH_P_ALL, ETH_PNIO, ETH_LLDP, ETH_VLAN = 0x0003, 0x8892, 0x88CC, 0x8100
DCP_MCAST, LLDP_MCAST = bytes.fromhex("010ecf000000"), bytes.fromhex("0180c200000e")
RPC_PORT = 34964
DEVICE_IF = uuid.UUID("dea00001-6c97-11d1-8271-00a02442df7d")
CONTROLLER_IF = uuid.UUID("dea00002-6c97-11d1-8271-00a02442df7d")
OBJECT = uuid.UUID("dea00000-6c97-11d1-8271-0001000102a2")   # instance 1, device 0001h, vendor 02A2h
STATION = "plc-s7"
SCF, RR = 32, 16                 # 16 ms cycle: a Python controller on a loaded machine holds it
HOLD = 125                       # watchdog / data hold factor: 2 s (a loaded 2-core machine stalls threads)
RUN, STOP = 0x35, 0x25           # DataStatus: primary, valid, provider RUN/STOP, station OK
GOOD = 0x80
MY_ALARM_REF = 0x0003
SUBMODULES = ((0, 1, 0x1, 0x1, 0, 0), (0, 0x8000, 0x1, 0x2, 0, 0), (0, 0x8001, 0x1, 0x3, 0, 0),
              (1, 1, 0x10, 0x11, 12, 8))   # slot, subslot, module, submodule, inputs, outputs


def out(**kw: Any) -> None:
    print(json.dumps(kw, default=str), flush=True)


def mac_of(iface: str) -> bytes:
    with open(f"/sys/class/net/{iface}/address") as f:
        return bytes.fromhex(f.read().strip().replace(":", ""))


def block(btype: int, body: bytes, low: int = 0) -> bytes:
    return struct.pack("!HHBB", btype, len(body) + 2, 1, low) + body


def blocks(data: bytes) -> list[tuple[int, bytes]]:
    res, off = [], 0
    while off + 6 <= len(data):
        btype, blen = struct.unpack_from("!HH", data, off)
        res.append((btype, data[off + 6:off + 4 + blen]))
        off += 4 + blen
    return res


@dataclass
class Wire:
    """The raw socket: one receiver thread sorting frames by kind."""

    iface: str
    mac: bytes = b""
    sock: socket.socket = field(init=False)
    dcp: queue.Queue[bytes] = field(default_factory=queue.Queue)
    alarms: queue.Queue[bytes] = field(default_factory=queue.Queue)
    lldp: list[bytes] = field(default_factory=list)
    inputs: dict[int, tuple[float, bytes]] = field(default_factory=dict)   # frame id → (time, payload)
    input_frames: int = 0
    stopped: bool = False

    def __post_init__(self) -> None:
        self.mac = mac_of(self.iface)
        self.sock = socket.socket(socket.AF_PACKET, socket.SOCK_RAW, socket.htons(ETH_P_ALL))
        self.sock.bind((self.iface, 0))
        self.sock.settimeout(0.2)
        threading.Thread(target=self._receive, daemon=True).start()

    def send(self, dst: bytes, ethertype: int, payload: bytes, tag: bool = False) -> None:
        frame = dst + self.mac + (struct.pack("!HH", ETH_VLAN, 0xC000) if tag else b"")
        frame += struct.pack("!H", ethertype) + payload
        self.sock.send(frame + bytes(max(0, 60 - len(frame))))

    def _receive(self) -> None:
        while not self.stopped:
            try:
                data, addr = self.sock.recvfrom(2048)
            except TimeoutError:
                continue
            except OSError:
                return
            if addr[2] == socket.PACKET_OUTGOING or len(data) < 16:
                continue
            off = 12
            etype = int.from_bytes(data[12:14], "big")
            if etype == ETH_VLAN:
                off, etype = 16, int.from_bytes(data[16:18], "big")
            payload = data[off + 2:]
            if etype == ETH_LLDP:
                self.lldp.append(payload)
            elif etype == ETH_PNIO and len(payload) >= 2:
                fid = int.from_bytes(payload[:2], "big")
                if fid in (0xFEFD, 0xFEFF):
                    self.dcp.put(data[6:12] + payload)
                elif fid in (0xFE01, 0xFC01):
                    self.alarms.put(payload)
                elif 0xC000 <= fid < 0xFC00:
                    self.inputs[fid] = (time.monotonic(), payload)
                    self.input_frames += 1


# --- DCP ----------------------------------------------------------------------------------------------
def dcp_identify(w: Wire, name: str) -> tuple[bytes, dict[tuple[int, int], bytes]]:
    """Identify by NameOfStation: the answering MAC and its blocks."""
    raw = name.encode()
    blk = struct.pack("!BBH", 2, 2, len(raw)) + raw + (b"\0" if len(raw) & 1 else b"")
    xid = 0x5A0001
    w.send(DCP_MCAST, ETH_PNIO, struct.pack("!HBBIHH", 0xFEFE, 5, 0, xid, 1, len(blk)) + blk)
    deadline = time.monotonic() + 3
    while time.monotonic() < deadline:
        try:
            frame = w.dcp.get(timeout=0.2)
        except queue.Empty:
            continue
        src, p = frame[:6], frame[6:]
        fid, sid, stype, rxid, _r, length = struct.unpack_from("!HBBIHH", p)
        if (fid, sid, stype, rxid) != (0xFEFF, 5, 1, xid):
            continue
        found, off = {}, 12
        while off + 4 <= 12 + length:
            o, s, n = struct.unpack_from("!BBH", p, off)
            found[(o, s)] = p[off + 4:off + 4 + n]
            off += 4 + n + (n & 1)
        return src, found
    raise SystemExit(f"no DCP Identify answer from {name!r}")


def dcp_set_ip(w: Wire, mac: bytes, ip: str, mask: str) -> int:
    """Set IP (temporary), as TIA's "assign IP address" does; the BlockError of the answer."""
    value = struct.pack("!H", 0) + socket.inet_aton(ip) + socket.inet_aton(mask) + bytes(4)
    blk = struct.pack("!BBH", 1, 2, len(value)) + value
    xid = 0x5A0002
    w.send(mac, ETH_PNIO, struct.pack("!HBBIHH", 0xFEFD, 4, 0, xid, 0, len(blk)) + blk)
    deadline = time.monotonic() + 3
    while time.monotonic() < deadline:
        try:
            p = w.dcp.get(timeout=0.2)[6:]
        except queue.Empty:
            continue
        fid, sid, stype, rxid = struct.unpack_from("!HBBI", p)
        if (fid, sid, rxid) == (0xFEFD, 4, xid) and stype == 1:
            return p[12 + 4 + 2]   # Control/Response block: option, suboption, BlockError
    raise SystemExit("no DCP Set answer")


# --- LLDP ---------------------------------------------------------------------------------------------
def tlv(kind: int, value: bytes) -> bytes:
    return struct.pack("!H", kind << 9 | len(value)) + value


def send_lldp(w: Wire) -> None:
    pdu = (tlv(1, b"\x07" + STATION.encode()) + tlv(2, b"\x07port-001." + STATION.encode())
           + tlv(3, struct.pack("!H", 20)) + tlv(0, b""))
    w.send(LLDP_MCAST, ETH_LLDP, pdu)


def read_lldp(payload: bytes) -> dict[str, Any]:
    found: dict[str, Any] = {}
    off = 0
    while off + 2 <= len(payload):
        head, = struct.unpack_from("!H", payload, off)
        kind, n = head >> 9, head & 0x1FF
        v = payload[off + 2:off + 2 + n]
        off += 2 + n
        if kind == 0:
            break
        if kind == 1:
            found["chassis"] = v[1:].decode()
        elif kind == 2:
            found["port"] = v[1:].decode()
        elif kind == 3:
            found["ttl"] = struct.unpack("!H", v)[0]
        elif kind == 127:
            found.setdefault("org", []).append(v[:4].hex())
    return found


# --- DCE/RPC ------------------------------------------------------------------------------------------
class Rpc:
    """Connectionless DCE/RPC over UDP 34964, little endian (DREP 10h), as Siemens controllers send it."""

    def __init__(self, device_ip: str) -> None:
        self.device = (device_ip, RPC_PORT)
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("0.0.0.0", RPC_PORT))   # nosec B104: the controller namespace of the test
        self.sock.settimeout(0.5)
        self.activity = uuid.uuid4()
        self.seq = 0
        self.calls: queue.Queue[tuple[bytes, tuple[str, int]]] = queue.Queue()   # the device's requests

    @staticmethod
    def header(ptype: int, obj: uuid.UUID, iface: uuid.UUID, activity: uuid.UUID, seq: int, opnum: int,
               body_len: int, boot: int = 0) -> bytes:
        return (struct.pack("<BBBB3sB", 4, ptype, 0x20, 0, b"\x10\x00\x00", 0) + obj.bytes_le + iface.bytes_le
                + activity.bytes_le + struct.pack("<IIIHHHHHBB", boot, 1, seq, opnum, 0xFFFF, 0xFFFF, body_len,
                                                  0, 0, 0))

    def call(self, opnum: int, args: bytes) -> tuple[int, bytes]:
        """One request; (PNIOStatus as ErrorCode<<24|..., the blocks of the answer)."""
        self.seq += 1
        body = struct.pack("<IIIII", 4096, len(args), 4096, 0, len(args)) + args
        req = self.header(0, OBJECT, DEVICE_IF, self.activity, self.seq, opnum, len(body)) + body
        for _try in range(6):
            self.sock.sendto(req, self.device)
            deadline = time.monotonic() + 1.0
            while time.monotonic() < deadline:
                try:
                    data, addr = self.sock.recvfrom(4096)
                except TimeoutError:
                    break
                if data[1] == 0:          # a request: the device's CControl (ApplicationReady)
                    self.calls.put((data, addr))
                    continue
                seq, = struct.unpack_from("<I", data, 64)
                if data[1] == 2 and uuid.UUID(bytes_le=data[40:56]) == self.activity and seq == self.seq:
                    status, n = struct.unpack_from("<II", data, 80)
                    return status, data[100:100 + n]
        raise SystemExit(f"no answer to RPC opnum {opnum}")

    def wait_call(self, timeout: float) -> tuple[bytes, tuple[str, int]] | None:
        """The next request the device sends us."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            try:
                return self.calls.get_nowait()
            except queue.Empty:
                pass
            try:
                data, addr = self.sock.recvfrom(4096)
            except TimeoutError:
                continue
            if data[1] == 0:
                return data, addr
        return None

    def answer(self, request: bytes, addr: tuple[str, int], blocks_: bytes) -> None:
        """A response with PNIOStatus OK to ``request`` (same activity and sequence number)."""
        activity = uuid.UUID(bytes_le=request[40:56])
        obj = uuid.UUID(bytes_le=request[8:24])
        seq, opnum = struct.unpack_from("<IH", request, 64)
        boot, = struct.unpack_from("<I", request, 56)
        body = struct.pack("<IIIII", 0, len(blocks_), len(blocks_), 0, len(blocks_)) + blocks_
        self.sock.sendto(self.header(2, obj, CONTROLLER_IF, activity, seq, opnum, len(body), boot) + body, addr)


def read_req(ar: uuid.UUID, slot: int, subslot: int, index: int, seq: int = 1) -> bytes:
    return block(0x0009, struct.pack("!H", seq) + ar.bytes + struct.pack("!IHHHHI", 0, slot, subslot, 0, index, 4096)
                 + bytes(24))


def write_req(ar: uuid.UUID, api: int, slot: int, subslot: int, index: int, data: bytes, seq: int = 1) -> bytes:
    return block(0x0008, struct.pack("!H", seq) + ar.bytes
                 + struct.pack("!IHHHHI", api, slot, subslot, 0, index, len(data)) + bytes(24)) + data


def control(btype: int, ar: uuid.UUID, session: int, command: int) -> bytes:
    return block(btype, b"\0\0" + ar.bytes + struct.pack("!HHHH", session, 0, command, 0))


# --- the AR -------------------------------------------------------------------------------------------
@dataclass
class Layout:
    """Offsets in the two IOCR frames (C_SDU), as this controller lays them out."""

    in_iops: dict[tuple[int, int], int] = field(default_factory=dict)
    in_data: int = 0          # the WSG's 12 input bytes
    out_data: int = 0         # the WSG's 8 output bytes
    out_iops: int = 0
    out_iocs: list[int] = field(default_factory=list)
    length: int = 40


def connect_args(ar: uuid.UUID, session: int, mac: bytes) -> tuple[bytes, Layout]:
    lay = Layout()
    arb = block(0x0101, struct.pack("!H", 1) + ar.bytes + struct.pack("!H", session) + mac + uuid.uuid4().bytes
                + struct.pack("!IHHH", 0x40000011, 600, 0x8892, len(STATION)) + STATION.encode())
    # input CR: IOPS of the three DAP submodules, the WSG's 12 bytes and IOPS, then its IOCS
    ins, off = b"", 0
    for slot, sub, _m, _s, inp, _o in SUBMODULES:
        ins += struct.pack("!HHH", slot, sub, off)
        if (slot, sub) == (1, 1):
            lay.in_data = off
        lay.in_iops[(slot, sub)] = off + inp
        off += inp + 1
    in_iocs = struct.pack("!HHH", 1, 1, off)
    # output CR: the WSG's 8 bytes and IOPS, then the IOCS of every submodule
    outs = struct.pack("!HHH", 1, 1, 0)
    lay.out_data, lay.out_iops = 0, 8
    out_iocs, off = b"", 9
    for slot, sub, *_ in SUBMODULES:
        out_iocs += struct.pack("!HHH", slot, sub, off)
        lay.out_iocs.append(off)
        off += 1

    def iocr(typ: int, ref: int, fid: int, objs: bytes, iocs: bytes) -> bytes:
        return block(0x0102, struct.pack("!HHHIHHHHHHIHHH", typ, ref, 0x8892, 1, lay.length, fid, SCF, RR, 1, 0,
                                         0xFFFFFFFF, HOLD, HOLD, 0xC000) + bytes(6)
                     + struct.pack("!HIH", 1, 0, len(objs) // 6) + objs + struct.pack("!H", len(iocs) // 6) + iocs)

    # RTA timeout 1 s (factor 10), 3 retries: an acknowledgement late by a stalled thread is no lost alarm
    alarm = block(0x0103, struct.pack("!HHIHHHHHH", 1, 0x8892, 0, 10, 3, MY_ALARM_REF, 200, 0xC000, 0xA000))
    expected = b""
    for slot in (0, 1):
        subs = [s for s in SUBMODULES if s[0] == slot]
        body = struct.pack("!HIHIHH", 1, 0, slot, subs[0][2], 0, len(subs))
        for _slot, sub, _m, ident, inp, outp in subs:
            kind = 3 if inp and outp else 0
            body += struct.pack("!HIH", sub, ident, kind) + struct.pack("!HHBB", 1, inp, 1, 1)
            if kind == 3:
                body += struct.pack("!HHBB", 2, outp, 1, 1)
        expected += block(0x0104, body)
    args = (arb + iocr(1, 1, 0xC001, ins, in_iocs) + iocr(2, 2, 0xFFFF, outs, out_iocs) + alarm + expected)
    return args, lay


class Cyclic:
    """The output frames every cycle from a thread: outputs, DataStatus, IOPS GOOD, IOCS GOOD."""

    def __init__(self, w: Wire, device_mac: bytes, frame_id: int, lay: Layout) -> None:
        self.w, self.dst, self.fid, self.lay = w, device_mac, frame_id, lay
        self.outputs = bytes(8)
        self.status = RUN
        self.counter = 0
        self.running = True
        self.sent = 0
        threading.Thread(target=self._run, daemon=True).start()

    def put(self, outputs: bytes, frames: int = 5) -> None:
        """New outputs, returning once ``frames`` frames carried them (a stalled sender thread must not
        let an image pass unseen: the device judges edges between the images it receives)."""
        self.outputs = outputs
        sent = self.sent
        wait_for(lambda: self.sent >= sent + frames, 10.0)

    def _run(self) -> None:
        period = SCF * RR * 31.25e-6
        nxt = time.monotonic()
        while self.running:
            c = bytearray(self.lay.length)
            c[self.lay.out_data:self.lay.out_data + 8] = self.outputs
            c[self.lay.out_iops] = GOOD
            for o in self.lay.out_iocs:
                c[o] = GOOD
            self.counter = (self.counter + SCF * RR) & 0xFFFF
            self.w.send(self.dst, ETH_PNIO, struct.pack("!H", self.fid) + bytes(c)
                        + struct.pack("!HBB", self.counter, self.status, 0), tag=True)
            self.sent += 1
            nxt += period
            time.sleep(max(0.0, nxt - time.monotonic()))


def inputs(w: Wire, fid: int, lay: Layout) -> tuple[InputImage, int, int, float] | None:
    """(the WSG's input image, its IOPS, the frame's DataStatus, age in s) of the newest input frame."""
    got = w.inputs.get(fid)
    if got is None:
        return None
    t, p = got
    c = p[2:2 + lay.length]
    status = p[2 + lay.length + 2]
    return (InputImage.unpack(bytes(c[lay.in_data:lay.in_data + 12])), c[lay.in_iops[(1, 1)]], status,
            time.monotonic() - t)


def wait_for(pred: Any, timeout: float) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if pred():
            return True
        time.sleep(0.02)
    return False


class Alarms:
    """The controller's end of the alarm CR: ACK each DATA-RTA-PDU, then send the AlarmAck (RTA level 2)."""

    def __init__(self, w: Wire, device_mac: bytes, device_ref: int) -> None:
        self.w, self.dst, self.ref = w, device_mac, device_ref
        self.send_seq, self.send_seq_o = 0xFFFF, 0xFFFE
        self.got: list[dict[str, Any]] = []
        self.acked_by_device = 0
        self.last_seq: int | None = None   # the device's last DATA: a retransmission of it is no new alarm

    def _rta(self, kind: int, flags: int, seq: int, ack: int, pdu: bytes) -> None:
        self.w.send(self.dst, ETH_PNIO, struct.pack("!HHHBBHHH", 0xFE01, self.ref, MY_ALARM_REF, 0x10 | kind,
                                                    flags, seq, ack, len(pdu)) + pdu, tag=True)

    def pump(self, timeout: float, alarms: int = -1) -> None:
        """Answer what comes for ``timeout`` s, or until ``alarms`` alarms have come and all our AlarmAcks
        are confirmed."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if len(self.got) == alarms and self.acked_by_device == alarms:
                return
            try:
                p = self.w.alarms.get(timeout=0.05)
            except queue.Empty:
                continue
            _fid, _dst, _src, ptype, _flags, seq, ack, n = struct.unpack_from("!HHHBBHHH", p)
            kind = ptype & 0x0F
            if kind == 3 and ack == self.send_seq_o:   # the device's ACK of our AlarmAck
                self.acked_by_device += 1
                continue
            if kind != 1:
                continue
            if seq == self.last_seq:   # our ACK came late: the device sent it again; confirm it again
                self._rta(3, 0x01, self.send_seq_o, seq, b"")
                continue
            self.last_seq = seq
            pdu = p[14:14 + n]
            btype, = struct.unpack_from("!H", pdu)
            atype, api, slot, sub, _mod, _smod, spec = struct.unpack_from("!HIHHIIH", pdu, 6)
            usi, = struct.unpack_from("!H", pdu, 26)
            items = [struct.unpack_from("!HHH", pdu, o) for o in range(28, len(pdu) - 5, 6)]
            self.got.append({"block": btype, "type": atype, "slot": slot, "subslot": sub, "usi": usi,
                             "items": [[et, props >> 11 & 3] for _ch, props, et in items]})
            self._rta(3, 0x01, self.send_seq_o, seq, b"")                    # transport: ACK-RTA-PDU
            ack_body = struct.pack("!HIHHHI", atype, api, slot, sub, spec, 0)
            self._rta(1, 0x11, self.send_seq, seq, block(0x8002, ack_body))  # application: AlarmAck-Low
            self.send_seq_o, self.send_seq = self.send_seq, (self.send_seq + 1) & 0x7FFF


def startup(iface: str, name: str, device_ip: str) -> None:
    w = Wire(iface)
    res: dict[str, Any] = {}
    t0 = time.monotonic()
    device_mac, found = dcp_identify(w, name)
    res["identify"] = {"mac": device_mac.hex(), "ip_before": socket.inet_ntoa(found.get((1, 2), bytes(6))[2:6]),
                       "name": found.get((2, 2), b"")[2:].decode()}
    res["set_ip"] = dcp_set_ip(w, device_mac, device_ip, "255.255.255.0")
    send_lldp(w)
    wait_for(lambda: any(p for p in w.lldp), 7.0)   # the device sends at least every 5 s
    res["device_lldp"] = read_lldp(w.lldp[-1]) if w.lldp else None

    rpc = Rpc(device_ip)
    ar_uuid, session = uuid.uuid4(), 1
    args, lay = connect_args(ar_uuid, session, w.mac)
    status, answer = rpc.call(0, args)
    got = blocks(answer)
    res["connect"] = {"status": status, "blocks": [hex(t) for t, _ in got]}
    iocr = {struct.unpack_from("!H", body)[0]: struct.unpack_from("!H", body, 4)[0] for t, body in got
            if t == 0x8102}
    device_ref = next(struct.unpack_from("!H", body, 2)[0] for t, body in got if t == 0x8103)
    in_fid, out_fid = iocr[1], iocr[2]
    cyc = Cyclic(w, device_mac, out_fid, lay)

    # PDEV writes as the engineering tool's project has them: one WriteMultiple
    peers = bytes([1, 8]) + b"port-001" + bytes([len(STATION)]) + STATION.encode()
    peers += bytes(-(6 + len(peers)) % 4)
    check = block(0x0200, b"\0\0" + struct.pack("!HH", 0, 0x8001) + block(0x020A, peers)
                  + block(0x020C, struct.pack("!H", 0x0010)))
    adjust = block(0x0202, b"\0\0" + struct.pack("!HH", 0, 0x8001)
                   + block(0x0224, b"\0\0" + struct.pack("!IH", 0, 0) + b"\0\0")
                   + block(0x0225, b"\0\0" + struct.pack("!IH", 0, 0) + b"\0\0"))
    itf = block(0x0250, b"\0\0" + struct.pack("!I", 1))
    multi = b""
    for seq, (sub, index, data) in enumerate(((0x8001, 0x802B, check), (0x8001, 0x802F, adjust),
                                              (0x8000, 0x8071, itf)), start=2):
        multi += write_req(ar_uuid, 0, 0, sub, index, data, seq)
        multi += bytes(-len(multi) % 4)
    status, answer = rpc.call(3, write_req(ar_uuid, 0xFFFFFFFF, 0xFFFF, 0xFFFF, 0xE040, multi))
    res["write_multiple"] = {"status": status,
                             "each": [struct.unpack_from("!I", body, 38)[0] for t, body in blocks(answer)
                                      if t == 0x8008][1:]}
    im1 = block(0x0021, b"S7 startup test".ljust(32) + b"veth cell".ljust(22))
    res["im1_write"] = rpc.call(3, write_req(ar_uuid, 0, 0, 1, 0xAFF1, im1))[0]
    status, answer = rpc.call(2, read_req(ar_uuid, 0, 0x8001, 0x802A))
    real = answer[64:]
    n_own = real[12]
    peers_at = 6 + 7 + n_own
    res["pd_port_data_real"] = {"status": status, "own_port": real[13:13 + n_own].decode(),
                                "peers": real[peers_at], "raw": real.hex()}
    if real[peers_at]:
        off = peers_at + 1 + (-(peers_at + 1) % 4)
        pl = real[off]
        port = real[off + 1:off + 1 + pl].decode()
        sl = real[off + 1 + pl]
        station = real[off + 2 + pl:off + 2 + pl + sl].decode()
        res["pd_port_data_real"].update(peer_port=port, peer_station=station)
    res["pd_real_data"] = rpc.call(2, read_req(ar_uuid, 0, 0x8000, 0xF841))[0]
    status, answer = rpc.call(2, read_req(ar_uuid, 0, 1, 0xAFF0))
    res["im0"] = {"status": status, "order_id": answer[64 + 8:64 + 28].decode().strip(),
                  "im_supported": struct.unpack_from("!H", answer, len(answer) - 2)[0]}

    status, answer = rpc.call(4, control(0x0110, ar_uuid, session, 0x0001))
    res["prm_end"] = {"status": status, "command": struct.unpack_from("!H", blocks(answer)[0][1], 22)[0]}
    call = rpc.wait_call(5.0)
    res["application_ready"] = None
    if call is not None:
        req, addr = call
        ctl = blocks(req[100:])[0]
        res["application_ready"] = {"block": hex(ctl[0]), "command": struct.unpack_from("!H", ctl[1], 22)[0]}
        rpc.answer(req, addr, control(0x8112, ar_uuid, session, 0x0008))
    wait_for(lambda: (i := inputs(w, in_fid, lay)) is not None and i[1] == GOOD, 3.0)
    first = inputs(w, in_fid, lay)
    res["inputs_after_ready"] = None if first is None else {"iops": first[1], "status": first[2]}

    # a diagnosis alarm: FASTSTOP raised (appears) and acknowledged (STOP/ACK: disappears)
    alarms = Alarms(w, device_mac, device_ref)
    cyc.put(OutputImage(CmdFlag.FASTSTOP).pack())
    alarms.pump(30.0, alarms=1)   # generous: a loaded CI machine once had only the second alarm after 10 s
    cyc.put(bytes(8))
    cyc.put(OutputImage(CmdFlag.STOP_ACK).pack())
    alarms.pump(30.0, alarms=2)
    cyc.put(bytes(8))
    alarms.pump(0.3)   # nothing more may come
    res["alarms"] = alarms.got
    res["alarm_acks_confirmed"] = alarms.acked_by_device

    # cyclic data: HOMING, then JOG with the provider in RUN
    cyc.put(OutputImage(CmdFlag.HOMING).pack())
    homed = wait_for(lambda: (i := inputs(w, in_fid, lay)) is not None and bool(i[0].sysstate & 1)
                     and i[0].state is not None and i[0].state.name == "IDLE", 15.0)
    cyc.outputs = bytes(8)
    time.sleep(0.2)
    now = inputs(w, in_fid, lay)
    assert now is not None
    res["homed"] = homed
    jog = CmdFlag.JOG_PLUS if now[0].width_mm < 50 else CmdFlag.JOG_MINUS
    cyc.outputs = OutputImage(jog, speed=2000).pack()        # 20 mm/s

    def travel(settle: float, span: float) -> tuple[float, tuple[InputImage, int, int, float]]:
        """How far the fingers moved in ``span`` s, after ``settle`` s; the last inputs."""
        time.sleep(settle)
        first = inputs(w, in_fid, lay)
        time.sleep(span)
        last = inputs(w, in_fid, lay)
        assert first is not None and last is not None
        return round(abs(last[0].width_mm - first[0].width_mm), 2), last

    res["jog_run_mm"], _last = travel(0.1, 0.4)
    # ProviderState STOP with JOG still in the image (as a PLC going to STOP leaves it)
    cyc.status = STOP
    res["jog_stop_mm"], s1 = travel(0.2, 0.5)
    res["inputs_during_stop"] = {"age_s": round(s1[3], 3), "iops": s1[1]}
    # back to RUN with GOOD data, the image cleared: the AR goes on
    cyc.outputs = bytes(8)
    cyc.status = RUN
    before = w.input_frames
    time.sleep(1.0)
    back = inputs(w, in_fid, lay)
    res["after_run"] = {"frames": w.input_frames - before, "iops": None if back is None else back[1],
                        "state": None if back is None else str(back[0].state)}

    status, answer = rpc.call(1, control(0x0114, ar_uuid, session, 0x0004))
    res["release"] = {"status": status, "command": struct.unpack_from("!H", blocks(answer)[0][1], 22)[0]}
    cyc.running = False
    time.sleep(0.3)
    before = w.input_frames
    time.sleep(0.5)
    res["frames_after_release"] = w.input_frames - before
    res["seconds"] = round(time.monotonic() - t0, 2)
    res["outputs_sent"] = cyc.sent
    w.stopped = True
    out(**res)


def im_after_restart(iface: str, name: str, device_ip: str) -> None:
    """Set IP by name again (a restart forgets a temporary IP), then an implicit read of I&M1."""
    w = Wire(iface)
    mac, _found = dcp_identify(w, name)
    dcp_set_ip(w, mac, device_ip, "255.255.255.0")
    rpc = Rpc(device_ip)
    status, answer = rpc.call(5, read_req(uuid.UUID(int=0), 0, 1, 0xAFF1))
    w.stopped = True
    out(status=status, im1=answer[64 + 6:].decode(errors="replace"))


def main() -> None:
    iface, scenario, name, ip = sys.argv[1:5]
    {"startup": startup, "im": im_after_restart}[scenario](iface, name, ip)


if __name__ == "__main__":
    main()
