"""Issue 23 items 6, 11 and 12: captures and logs that `wsg decode -f` and `wsg replay` read —
damaged files are one line (replay: exit 2), reading is linear, UDP direction comes from who spoke
first. Costs are ratios between two sizes of the same input in one test, never seconds."""

from __future__ import annotations

import json
import struct
import time
from pathlib import Path

import pytest

from pywsg.capture.reader import frames_from_capture, frames_from_jsonl
from pywsg.protocol import Frame, Status
from pywsg.testing.proxy import PcapWriter
from pywsg.testing.replay import load_steps

from .conftest import run_wsg

CLIENT, SERVER = ("127.0.0.1", 40000), ("127.0.0.1", 40001)  # no default WSG port on either side


def _capture(path: Path, segments: int, skip_first: bool = False) -> Path:
    w = PcapWriter(path)
    w.tcp_open(CLIENT, SERVER, 1.0)
    if skip_first:  # the first data segment never reached the capture
        w._seq[(*CLIENT, *SERVER)] += 10
    for i in range(segments):
        w.tcp(CLIENT, SERVER, Frame(0x06, i.to_bytes(4, "little")).encode(), 1.0 + i * 1e-3)
        w.tcp(SERVER, CLIENT, Frame.reply(0x06, Status.E_SUCCESS, i.to_bytes(4, "little")).encode(), 1.0 + i * 1e-3)
    w.close()
    return path


def test_truncated_pcap_keeps_what_was_read_and_says_where_it_ended(tmp_path: Path) -> None:
    """Before: a 41-55-line traceback (dpkt NeedData). Now the frames read plus one line; replay, whose
    comparison needs the whole recording, refuses it with its bad-input status 2."""
    path = _capture(tmp_path / "cut.pcapng", 20)
    path.write_bytes(path.read_bytes()[:-30])
    frames = frames_from_capture(path)
    assert sum(f.decoded.command_id == 0x06 for f in frames) >= 30
    assert "capture damaged after packet" in (frames[-1].decoded.error or "")
    r = run_wsg("decode", "-f", str(path))
    assert r.code == 1 and "capture damaged" in r.out and "Traceback" not in r.err, r.err  # 1: errors shown
    r = run_wsg("replay", str(path), "--to", "tcp://127.0.0.1:1")
    assert r.code == 2 and "capture damaged" in r.err and "Traceback" not in r.err, r.err


def test_pcapng_block_with_a_huge_length_is_one_line(tmp_path: Path) -> None:
    path = _capture(tmp_path / "huge.pcapng", 3)
    data = path.read_bytes() + struct.pack("<II", 6, 0x7FFFFFF0) + b"\x00" * 64  # an EPB claiming 2 GiB
    path.write_bytes(data)
    r = run_wsg("decode", "-f", str(path))
    assert "Traceback" not in r.err and "capture damaged" in r.out, r.out + r.err


@pytest.mark.parametrize("line, why", [
    ('{"time": [1], "direction": "tx", "hex": "AA AA AA 06 00 00 E4 C7"}', "time"),
    ('{"time": 1' + "0" * 400 + ', "direction": "tx", "hex": "AA AA AA 06 00 00 E4 C7"}', "time"),
    ('{"time": 1, "direction": "tx", "hex": ' + "[" * 2000 + "]" * 2000 + "}", "not a JSON object"),
])
def test_bad_json_lines_are_one_line_and_replay_exits_2(tmp_path: Path, line: str, why: str) -> None:
    path = tmp_path / "bad.jsonl"
    path.write_text('{"time": 1.0, "direction": "tx", "hex": "AA AA AA 06 00 00 E4 C7"}\n' + line + "\n")
    with pytest.raises(ValueError, match=why):
        frames_from_jsonl(path)
    r = run_wsg("decode", "-f", str(path))
    assert r.code != 0 and "line 2" in r.err and "Traceback" not in r.err, r.err
    assert len(r.err.strip().splitlines()) <= 4
    r = run_wsg("replay", str(path), "--to", "tcp://127.0.0.1:1")
    assert r.code == 2 and "line 2" in r.err and "Traceback" not in r.err, r.err


def _cpu(fn: object, *args: object) -> float:
    t0 = time.process_time()
    fn(*args)  # type: ignore[operator]
    return time.process_time() - t0


def test_capture_with_its_first_segment_missing_reads_in_linear_time(tmp_path: Path) -> None:
    """Before: every later segment was held behind the gap and all of them re-scanned per segment
    (20k segments: 57 s). Four times the segments must cost far less than 16 times as much."""
    small = _capture(tmp_path / "s.pcapng", 1000, skip_first=True)
    big = _capture(tmp_path / "b.pcapng", 4000, skip_first=True)
    frames = frames_from_capture(big)
    assert sum(f.decoded.command_id == 0x06 for f in frames) >= 7990
    assert any("missing from the capture" in (f.decoded.error or "") for f in frames)
    base = min(_cpu(frames_from_capture, small) for _ in range(2))
    cost = min(_cpu(frames_from_capture, big) for _ in range(2))
    assert cost < 8 * base, (cost, base)


def test_replay_step_matching_is_linear_in_unmatched_replies(tmp_path: Path) -> None:
    """Before: each reply searched every earlier step (20k unmatched replies: 15 s)."""
    def log(n: int) -> Path:
        path = tmp_path / f"r{n}.jsonl"
        lines = [json.dumps({"time": 0, "direction": "tx", "hex": Frame(0x06, b"x").encode().hex(" ")})] * n
        lines += [json.dumps({"time": 0, "direction": "rx",
                              "hex": Frame.reply(0x43, Status.E_SUCCESS, b"\0" * 4).encode().hex(" ")})] * n
        path.write_text("\n".join(lines) + "\n")
        return path

    small, big = log(1000), log(4000)
    assert len(load_steps(big)) == 4000
    base = min(_cpu(load_steps, small) for _ in range(2))
    cost = min(_cpu(load_steps, big) for _ in range(2))
    assert cost < 8 * base, (cost, base)


def test_udp_direction_comes_from_who_spoke_first_not_the_bytes(tmp_path: Path) -> None:
    """Before: on ports other than 1500/1501, a 41h request (status-less, its payload byte-identical to
    an IDLE reply's) was labelled a reply. The side that sent first is the client."""
    w = PcapWriter(tmp_path / "udp.pcapng")
    request = Frame(0x41, b"\x00\x00").encode()  # auto-update off, "only changes" off
    reply = Frame.reply(0x41, Status.E_SUCCESS, b"\x00\x00").encode()
    for i in range(3):
        w.udp(CLIENT, SERVER, request, 1.0 + i)
        w.udp(SERVER, CLIENT, reply, 1.5 + i)
    w.close()
    frames = [f for f in frames_from_capture(tmp_path / "udp.pcapng") if f.decoded.command_id == 0x41]
    assert [f.decoded.direction for f in frames] == ["request", "reply"] * 3
