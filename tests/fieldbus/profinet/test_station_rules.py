"""DCP and the station to the standard's rules (issue 31 items 10-13; IEC 61158-6-10 DCP and CMINA): Reset to
Factory by mode, one policy for DCP Set/Reset during an AR, NameOfStation compared as written, startup
supervision by the CMInitiatorActivityTimeout, refused packets logged at a bounded rate. Sans-IO: the real
DCP responder, connection manager and device (on ``lo``, no socket opened), fed the frames a controller sends."""

from __future__ import annotations

import json
import logging
import random
import struct
from pathlib import Path

import pytest

from pywsg.fieldbus.profinet import rpc
from pywsg.fieldbus.profinet.ar import ARState
from pywsg.fieldbus.profinet.dcp import DcpHandlers, DcpResponder
from pywsg.fieldbus.profinet.device import ProfinetDevice
from pywsg.fieldbus.profinet.ether import ether, mac_text
from pywsg.fieldbus.profinet.refusals import RefusalLog
from pywsg.fieldbus.profinet.station import IpSuite, PermanentStore

from ..test_controller import Rig
from .test_sans_io import MAC, MCAST, REAL_EXPECTED, _blocks_of, _connect_args, _dcp_frame, _rpc_request, _station
from .tshark import counts, flagged, needs_tshark, write_pcap

RESET = (5, 6)


def _reset_block(mode: int) -> bytes:
    return struct.pack("!BBHH", 5, 6, 2, mode << 1)


def test_identify_by_name_compares_as_written() -> None:
    """Valid names are lowercase: an Identify for "WSG50" is for another station than "wsg50" (before: it
    matched)."""
    dcp = DcpResponder(_station(), DcpHandlers(lambda n, p: 0, lambda s, p: 0, lambda: None, lambda m: 0))
    assert dcp.handle(_dcp_frame(MCAST, 0xFEFE, 5, b"\x02\x02\x00\x05WSG50\x00")) == []
    assert len(dcp.handle(_dcp_frame(MCAST, 0xFEFE, 5, b"\x02\x02\x00\x05wsg50\x00"))) == 1


def test_reset_to_factory_takes_only_the_declared_mode() -> None:
    """ResetToFactory mode 2 (communication parameters, the GSDML's ResetToFactoryModes) reaches the device;
    modes 1 (application data), 8, 9 (all data) and others are refused, BlockError 2, nothing cleared; the
    older FactoryReset suboption (5, 5) means mode 2."""
    modes: list[int] = []
    dcp = DcpResponder(_station(), DcpHandlers(lambda n, p: 0, lambda s, p: 0, lambda: None,
                                               lambda m: modes.append(m) or 0))
    for mode in (1, 8, 9, 16, 0):
        [(_, reply)] = dcp.handle(_dcp_frame(MAC, 0xFEFD, 4, _reset_block(mode)))
        assert _blocks_of(reply)[(5, 4)] == b"\x05\x06\x02", mode
    assert modes == []
    [(_, reply)] = dcp.handle(_dcp_frame(MAC, 0xFEFD, 4, _reset_block(2)))
    assert _blocks_of(reply)[(5, 4)] == b"\x05\x06\x00" and modes == [2]
    [(_, reply)] = dcp.handle(_dcp_frame(MAC, 0xFEFD, 4, struct.pack("!BBHH", 5, 5, 2, 0)))
    assert _blocks_of(reply)[(5, 4)] == b"\x05\x05\x00" and modes == [2, 2]


def _device(tmp_path: Path) -> tuple[ProfinetDevice, Path]:
    path = tmp_path / "settings.interface.json"
    path.write_text(json.dumps({"web_port": 8080}))
    rig = Rig()
    dev = ProfinetDevice(rig.g, "lo", rig.ctl, station_name="wsg50", store=PermanentStore(path))
    return dev, path


def test_reset_clears_the_permanent_ip_too_and_is_refused_during_an_ar(tmp_path: Path) -> None:
    """Mode 2 clears name and IP, running and stored (before: the stored IP came back after a restart); keys
    others own stay. During an IO AR a Reset is refused like a Set of name or IP (BlockError 6, "in
    operation"), and the AR goes on (before: the AR ended and the gripper FAST STOPped)."""
    dev, path = _device(tmp_path)
    assert dev._set_ip(IpSuite("192.168.0.20", "255.255.255.0", "192.168.0.1"), True) == 0
    assert dev._set_name("wsg-cell", True) == 0
    assert json.loads(path.read_text())["ip_address"] == "192.168.0.20"
    dev.cm.handle(_rpc_request(rpc.OP_CONNECT, _connect_args(REAL_EXPECTED)), "192.0.2.1", 1)
    ar = dev.cm.io_ar
    assert ar is not None
    assert dev._reset(2) == 6 and dev._set_name("other", False) == 6
    assert dev._set_ip(IpSuite("192.168.0.21", "255.255.255.0", "0.0.0.0"), False) == 6
    assert dev.cm.io_ar is ar and dev.station.name == "wsg-cell"
    dev.cm.drop(ar, "released by the controller")
    assert dev._reset(2) == 0
    stored = json.loads(path.read_text())
    assert stored == {"web_port": 8080, "profinet_name": ""}
    assert dev.station.name == "" and dev.station.ip == IpSuite() and not dev.ipstack.has_ip
    again = PermanentStore(path)   # after a restart
    assert again.ip() is None and again.name() == ""


def test_a_connect_without_prm_end_is_held_for_the_activity_timeout_only(tmp_path: Path) -> None:
    """CMInitiatorActivityTimeout (ARBlockReq: factor 100 × 100 ms = 10 s here) supervises parameterization
    from the controller's last request; then, until the first output frame, the same time from
    ApplicationReady; then the data hold time. Judged at injected times, no sleeping."""
    dev, _ = _device(tmp_path)
    dev.cm.handle(_rpc_request(rpc.OP_CONNECT, _connect_args(REAL_EXPECTED)), "192.0.2.1", 1)
    ar, codec = dev.cm.io_ar, dev.codec
    assert ar is not None and codec is not None and ar.request.timeout_factor == 100
    t0 = ar.last_activity
    assert dev._supervise(ar, codec, t0 + 9.9) == ""
    assert "no PrmEnd within the CMInitiatorActivityTimeout (10 s)" in dev._supervise(ar, codec, t0 + 10.1)
    dev._last_frame_t = t0 + 1.0   # output frames flowing do not stand in for PrmEnd
    assert "no PrmEnd" in dev._supervise(ar, codec, t0 + 10.1)
    ar.state, ar.last_activity, dev._last_frame_t = ARState.DATA, t0 + 5, 0.0
    assert dev._supervise(ar, codec, t0 + 14.9) == ""
    assert "no output frame" in dev._supervise(ar, codec, t0 + 15.1)
    dev._last_frame_t = t0 + 15.0
    hold = codec.out_cr.data_hold_factor * codec.out_cr.cycle_s
    assert dev._supervise(ar, codec, t0 + 15.0 + hold * 0.9) == ""
    assert "watchdog" in dev._supervise(ar, codec, t0 + 15.0 + hold * 1.1)


def test_refused_packets_log_at_a_bounded_rate(caplog: pytest.LogCaptureFixture) -> None:
    """6,000 broken RPC requests and bad DCP Sets: each answered, at most 10 WARNING lines per 10 s (before:
    one line each, 559 for a fuzz run); the next line logged says how many were left out."""
    dcp = DcpResponder(_station(), DcpHandlers(lambda n, p: 0, lambda s, p: 0, lambda: None, lambda m: 0))
    caplog.set_level(logging.WARNING)
    rnd = random.Random(1)
    from pywsg.fieldbus.profinet.ar import ConnectionManager, Identity

    cm = ConnectionManager(_station(), Identity("WSG 50", "1"))
    good = _rpc_request(rpc.OP_CONNECT, _connect_args(REAL_EXPECTED))
    answered = 0
    for i in range(3000):
        data = bytearray(good)
        data[rnd.randrange(80, len(data))] ^= 0xFF
        data[60:64] = struct.pack(">I", i)   # a new sequence number: no cached answer
        answered += cm.handle(bytes(data), "x", 1) is not None
        cm.io_ar = None
        dcp.handle(_dcp_frame(MAC, 0xFEFD, 4, b"\x02\x02\x00\x06\x00\x00Bad_N\x00"))
    assert answered == 3000
    lines = [r for r in caplog.records if r.levelno == logging.WARNING]
    assert 0 < len(lines) <= 20, len(lines)
    clock = [0.0]
    rl = RefusalLog(logging.getLogger("t"), burst=2, window=10.0, clock=lambda: clock[0])
    caplog.clear()
    for _ in range(5):
        rl.warn("refused %s", "x")
    clock[0] = 10.0
    rl.warn("refused %s", "y")
    assert [r.getMessage() for r in caplog.records] == ["refused x", "refused x",
                                                        "refused y (3 more refused since, not logged)"]


@needs_tshark
def test_wireshark_reads_the_dcp_answers_clean(tmp_path: Path) -> None:
    """Identify (all, by name), Get, Set, a refused and an accepted Reset to Factory, and garbage: every
    answer the responder builds decodes in tshark without Malformed or Error-level expert info (item 9)."""
    dcp = DcpResponder(_station(), DcpHandlers(lambda n, p: 0, lambda s, p: 0, lambda: None, lambda m: 0))
    requests = [_dcp_frame(MCAST, 0xFEFE, 5, b"\xff\xff\x00\x00"),
                _dcp_frame(MCAST, 0xFEFE, 5, b"\x02\x02\x00\x05wsg50\x00"),
                _dcp_frame(MAC, 0xFEFD, 3, b"\x02\x02\x01\x02\x02\x07\x05\x06"),
                _dcp_frame(MAC, 0xFEFD, 4, b"\x02\x02\x00\x0a\x00\x01new-name"),
                _dcp_frame(MAC, 0xFEFD, 4, _reset_block(9)),
                _dcp_frame(MAC, 0xFEFD, 4, _reset_block(2)),
                _dcp_frame(MAC, 0xFEFD, 4, b"\x02\x02\x00\x06\x00\x00Bad_N\x00")]
    frames = []
    for req in requests:
        frames.append(ether(req.dst, req.src, 0x8892, req.payload))
        frames.extend(reply for _delay, reply in dcp.handle(req))
    assert len(frames) == 2 * len(requests)
    pcap = write_pcap(tmp_path / "dcp.pcap", frames)
    assert flagged(pcap) == []
    assert counts(pcap, f"eth.src == {mac_text(MAC)} && pn_dcp") == len(requests)
