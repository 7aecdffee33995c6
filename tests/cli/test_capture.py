"""`wsg decode -f`: pcap/pcapng captures (TCP reassembled per direction, UDP datagrams) and hex dumps.

The captures are written here with dpkt (a maintained pcap library) so the awkward cases are
exact: a frame split over segments, segments out of order, a retransmission, an overlap, an
unrelated flow, a bad checksum. tshark (when installed) converts one to pcapng.
"""

from __future__ import annotations

import shutil
import socket
import subprocess
from pathlib import Path

import dpkt
import pytest

from pywsg.capture.reader import bytes_from_file, frames_from_capture, read_hexdump
from pywsg.protocol import Frame, Status

from .conftest import run_wsg

CLIENT, SERVER = ("127.0.0.1", 40000), ("127.0.0.1", 1000)
REQ = Frame(0x21, bytes.fromhex("00 00004842 0000c842")).encode()  # pre-position 50 mm, 100 mm/s
PENDING = bytes.fromhex("AA AA AA 21 02 00 1A 00 67 CB")  # the manual's example
DONE = bytes.fromhex("AA AA AA 21 02 00 00 00 28 04")
WIDTH_REQ = Frame(0x43, b"\x00\x00\x00").encode()
WIDTH_REPLY = Frame.reply(0x43, Status.E_SUCCESS, bytes.fromhex("00004842")).encode()


def _eth(ip: dpkt.ip.IP) -> bytes:
    ip.len = len(bytes(ip))
    return bytes(dpkt.ethernet.Ethernet(src=b"\x02" * 6, dst=b"\x02" * 6, type=0x0800, data=ip))


def tcp(src: tuple[str, int], dst: tuple[str, int], seq: int, data: bytes = b"",
        flags: int = dpkt.tcp.TH_ACK | dpkt.tcp.TH_PUSH) -> bytes:
    seg = dpkt.tcp.TCP(sport=src[1], dport=dst[1], seq=seq, flags=flags, data=data)
    return _eth(dpkt.ip.IP(src=socket.inet_aton(src[0]), dst=socket.inet_aton(dst[0]), p=6, data=seg))


def udp(src: tuple[str, int], dst: tuple[str, int], data: bytes) -> bytes:
    dg = dpkt.udp.UDP(sport=src[1], dport=dst[1], data=data)
    dg.ulen = len(bytes(dg))
    return _eth(dpkt.ip.IP(src=socket.inet_aton(src[0]), dst=socket.inet_aton(dst[0]), p=17, data=dg))


def conversation() -> list[tuple[float, bytes]]:
    c, s = CLIENT, SERVER
    cs, ss = 1000, 5000  # initial sequence numbers
    return [
        (1.0, tcp(c, s, cs, flags=dpkt.tcp.TH_SYN)),
        (1.0, tcp(s, c, ss, flags=dpkt.tcp.TH_SYN | dpkt.tcp.TH_ACK)),
        (1.1, tcp(c, s, cs + 1 + 7, REQ[7:])),  # second half first (out of order)
        (1.2, tcp(c, s, cs + 1, REQ[:7])),  # the gap fills: the request completes at 1.2
        (1.25, tcp(c, s, cs + 1, REQ[:7])),  # retransmission: ignored
        (1.3, tcp(s, c, ss + 1, PENDING + DONE[:4])),  # one segment: a frame and a half
        (2.0, tcp(s, c, ss + 1 + 10, DONE)),  # overlaps the 4 bytes already seen
        (2.1, tcp(("10.0.0.9", 5555), ("10.0.0.1", 80), 77, b"GET / HTTP/1.1\r\n\r\n")),  # not WSG
        (2.2, udp(("127.0.0.1", 50000), ("127.0.0.1", 1500), WIDTH_REQ)),
        (2.3, udp(("127.0.0.1", 1500), ("127.0.0.1", 1501), WIDTH_REPLY)),
    ]


def write_pcap(path: Path, packets: list[tuple[float, bytes]]) -> Path:
    with path.open("wb") as f:
        w = dpkt.pcap.Writer(f)
        for ts, pkt in packets:
            w.writepkt(pkt, ts)
    return path


def test_tcp_reassembly_and_udp(tmp_path: Path) -> None:
    frames = frames_from_capture(write_pcap(tmp_path / "c.pcap", conversation()))
    got = [(c.time, c.transport, c.decoded.direction, c.decoded.raw) for c in frames]
    assert got == [
        (1.2, "tcp", "request", REQ),
        (1.3, "tcp", "reply", PENDING),
        (2.0, "tcp", "reply", DONE),
        (2.2, "udp", "request", WIDTH_REQ),
        (2.3, "udp", "reply", WIDTH_REPLY),
    ]
    assert frames[0].src == "127.0.0.1:40000" and frames[0].dst == "127.0.0.1:1000"
    assert [v.value for v in frames[0].decoded.values][1:] == [50.0, 100.0]
    assert frames[1].decoded.status == "E_CMD_PENDING"
    assert frames[4].decoded.values[0].value == 50.0


def test_wsg_decode_pcap_text_and_json(tmp_path: Path) -> None:
    path = write_pcap(tmp_path / "c.pcap", conversation())
    r = run_wsg("decode", "-f", str(path))
    assert r.code == 0, r
    assert "TCP 127.0.0.1:40000 -> 127.0.0.1:1000" in r.out
    assert "request PREPOSITION (21h)" in r.out and "E_CMD_PENDING (26)" in r.out
    assert "HTTP" not in r.out and "10.0.0.9" not in r.out
    r = run_wsg("decode", "--json", "-f", str(path))
    data = r.json()
    assert [d["command"] for d in data] == ["PREPOSITION"] * 3 + ["GET_OPENING_WIDTH"] * 2
    assert [d["status"] for d in data] == [None, "E_CMD_PENDING", "E_SUCCESS", None, "E_SUCCESS"]
    assert data[3]["transport"] == "udp" and data[4]["params"] == {"width": 50.0}


def test_bad_checksum_in_capture_exits_1(tmp_path: Path) -> None:
    bad = DONE[:-1] + b"\x00"
    pkts = [(1.0, tcp(CLIENT, SERVER, 10, REQ)), (1.1, tcp(SERVER, CLIENT, 90, bad))]
    r = run_wsg("decode", "-f", str(write_pcap(tmp_path / "bad.pcap", pkts)))
    assert r.code == 1, r
    assert "checksum: WRONG, received 0028h, expected 0428h" in r.out


@pytest.mark.skipif(shutil.which("tshark") is None, reason="tshark not installed")
def test_pcapng_written_by_tshark(tmp_path: Path) -> None:
    src = write_pcap(tmp_path / "c.pcap", conversation())
    ng = tmp_path / "c.pcapng"
    subprocess.run(["tshark", "-r", str(src), "-F", "pcapng", "-w", str(ng)], check=True, capture_output=True)
    assert ng.read_bytes()[:4] == b"\x0a\x0d\x0d\x0a"
    r = run_wsg("decode", "--json", "-f", str(ng))
    assert r.code == 0, r
    assert [d["hex"] for d in r.json()][:3] == [x.hex(" ").upper() for x in (REQ, PENDING, DONE)]


def test_hex_dump_files_made_by_xxd_and_hexdump(tmp_path: Path) -> None:
    raw = tmp_path / "frames.bin"
    raw.write_bytes(PENDING + DONE)
    assert bytes_from_file(raw) == PENDING + DONE
    manual = tmp_path / "manual.txt"
    manual.write_text("# the manual's example\nAAh AAh AAh 21h 02h 00h 1Ah 00h 67h CBh\n"
                      "0xAA,0xAA,0xAA 21 02 00 00 00 28 04\n")
    assert bytes_from_file(manual) == PENDING + DONE
    for tool in (["xxd"], ["hexdump", "-C"]):
        if shutil.which(tool[0]) is None:
            continue
        dump = subprocess.run([*tool, str(raw)], check=True, capture_output=True, text=True).stdout
        assert read_hexdump(dump) == PENDING + DONE, tool
        (tmp_path / "dump.txt").write_text(dump)
        r = run_wsg("decode", "-f", str(tmp_path / "dump.txt"))
        assert r.code == 0, r
        assert r.out.count("reply PREPOSITION (21h)") == 2
    r = run_wsg("decode", "-f", str(manual), "--json")
    assert [d["status"] for d in r.json()] == ["E_CMD_PENDING", "E_SUCCESS"]


def test_not_hex_is_an_error(tmp_path: Path) -> None:
    p = tmp_path / "x.txt"
    p.write_text("hello world\n")
    r = run_wsg("decode", "-f", str(p))
    assert r.code == 1 and "not a hex byte" in r.err


def test_lost_segment_and_truncated_tail(tmp_path: Path) -> None:
    # client: REQ, then a segment is missing (never captured), then DONE; server: PENDING cut short
    pkts = [
        (1.0, tcp(CLIENT, SERVER, 100, REQ)),
        (1.1, tcp(CLIENT, SERVER, 100 + len(REQ) + 5, WIDTH_REQ)),  # 5 bytes before it were lost
        (1.2, tcp(SERVER, CLIENT, 900, PENDING[:6])),
    ]
    frames = frames_from_capture(write_pcap(tmp_path / "lossy.pcap", pkts))
    assert frames[0].decoded.raw == REQ
    errors = [c.decoded.error for c in frames if c.decoded.error]
    assert any("5 byte(s) missing" in (e or "") for e in errors)
    assert any(c.decoded.raw == WIDTH_REQ and c.decoded.error is None for c in frames)  # resynchronised
    tail = [c for c in frames if c.decoded.error and "truncated" in c.decoded.error]
    assert tail == []  # a stream without a complete frame is not reported (not WSG traffic, as far as we know)
    pkts.append((1.3, tcp(SERVER, CLIENT, 906, PENDING[6:] + DONE[:4])))
    frames = frames_from_capture(write_pcap(tmp_path / "lossy2.pcap", pkts))
    tail = [c for c in frames if c.decoded.error and "truncated" in c.decoded.error]
    assert len(tail) == 1 and tail[0].time == 1.3 and tail[0].src == "127.0.0.1:1000"
    r = run_wsg("decode", "-f", str(tmp_path / "lossy2.pcap"))
    assert r.code == 1 and "truncated frame: 4 bytes" in r.out, r
