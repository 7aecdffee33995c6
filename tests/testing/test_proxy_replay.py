"""`wsg proxy` and `wsg replay` as users meet them (issue 14 items 4 and 5): a raw-socket client and
pywsg's own driver through the tap, the recorded files read back by `wsg decode -f` and `wsg replay`."""

from __future__ import annotations

import json
import signal
import socket
import subprocess
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from pywsg.client import Gripper
from pywsg.protocol import Command, Frame, FrameParser
from pywsg.testing import SimThread

from .conftest import ENV, WSG, free_port, wsg


class ProxyProc:
    def __init__(self, target: str, *extra: str) -> None:
        self.port = free_port(socket.SOCK_DGRAM if target.startswith("udp") else socket.SOCK_STREAM)
        self.proc = subprocess.Popen([*WSG, "proxy", "--listen", str(self.port), "--to", target, *extra],
                                     stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=ENV)
        assert self.proc.stderr is not None
        line = self.proc.stderr.readline()
        assert line.startswith("proxy "), line

    def stop(self) -> tuple[str, str]:
        self.proc.send_signal(signal.SIGINT)
        out, err = self.proc.communicate(timeout=15)
        return out, err


@pytest.fixture
def sim() -> Iterator[SimThread]:
    with SimThread(udp_port=0) as s:
        yield s


def _raw_exchange(port: int, requests: list[bytes]) -> bytes:
    """A third-party client: raw bytes out, raw bytes back (HOMING's two replies included)."""
    with socket.create_connection(("127.0.0.1", port), timeout=10) as s:
        parser = FrameParser()
        received = b""
        for req in requests:
            s.sendall(req[:3])  # split frames must pass unchanged too
            time.sleep(0.01)
            s.sendall(req[3:])
            want = 2 if req[3] == Command.HOMING else 1
            frames: list[Frame] = []
            while len(frames) < want:
                chunk = s.recv(4096)
                assert chunk, "proxy closed the connection"
                received += chunk
                frames += [e for e in parser.feed(chunk) if isinstance(e, Frame)]
        return received


def test_raw_client_through_the_tcp_proxy_gets_identical_bytes(sim: SimThread, tmp_path: Path) -> None:
    requests = [Frame(Command.HOMING, b"\x00").encode(), Frame(Command.GET_OPENING_WIDTH, b"\x00\x00\x00").encode(),
                Frame(Command.GET_SYSTEM_STATE, b"\x00\x00\x00").encode(), Frame(Command.DISCONNECT).encode()]
    direct = _raw_exchange(sim.g.tcp_port or 0, requests)
    pcap, jsonl = tmp_path / "x.pcapng", tmp_path / "x.jsonl"
    proxy = ProxyProc(sim.url, "--pcap", str(pcap), "--jsonl", str(jsonl))
    proxied = _raw_exchange(proxy.port, requests)
    out, err = proxy.stop()
    assert proxied == direct  # same replies, same order, same bytes (after homing: at rest, same values)
    lines = out.splitlines()
    assert [ln.split()[1:4] for ln in lines] == [
        ["TX", "20h", "HOMING"], ["RX", "20h", "HOMING"], ["RX", "20h", "HOMING"],
        ["TX", "43h", "GET_OPENING_WIDTH"], ["RX", "43h", "GET_OPENING_WIDTH"],
        ["TX", "40h", "GET_SYSTEM_STATE"], ["RX", "40h", "GET_SYSTEM_STATE"],
        ["TX", "07h", "DISCONNECT"], ["RX", "07h", "DISCONNECT"],
    ]
    assert "E_CMD_PENDING" in lines[1] and "E_SUCCESS" in lines[2] and "width=110 mm" in lines[4]
    assert "4 request(s), 5 reply frame(s)" in err
    # the files: wsg decode -f reads the pcapng (directions from the SYN), JSON lines hold every frame
    r = wsg("decode", "-f", str(pcap), "--json")
    assert r.returncode == 0, r.stderr
    decoded = json.loads(r.stdout)
    assert [(d["direction"], d["command"]) for d in decoded][:3] == [
        ("request", "HOMING"), ("reply", "HOMING"), ("reply", "HOMING")]
    assert len(jsonl.read_text().splitlines()) == 9


def test_driver_through_udp_proxy(sim: SimThread) -> None:
    proxy = ProxyProc(sim.udp_url + "?reply_port=0", "--json")
    with Gripper(f"udp://127.0.0.1:{proxy.port}?reply_port=0") as g:
        g.home()
        assert g.width() == pytest.approx(110.0)
    out, _ = proxy.stop()
    entries = [json.loads(line) for line in out.splitlines()]
    assert {"tx", "rx"} <= {e["direction"] for e in entries}
    assert any(e["command"] == "GET_OPENING_WIDTH" and e["status"] == "E_SUCCESS" for e in entries)


def test_proxy_refuses_a_bad_target() -> None:
    r = wsg("proxy", "--listen", "0", "--to", "serial:///dev/null")
    assert r.returncode == 2 and "tcp:// or udp://" in r.stderr


def test_replay_matches_the_same_gripper_and_finds_a_different_one(sim: SimThread, tmp_path: Path) -> None:
    pcap = tmp_path / "session.pcapng"
    proxy = ProxyProc(sim.url, "--pcap", str(pcap), "-q")
    with Gripper(f"tcp://127.0.0.1:{proxy.port}") as g:
        g.home()
        g.width()
        g.move(50.0, speed=200)
        g.width()
    proxy.stop()
    with SimThread() as fresh:  # a fresh gripper answers the same way: match, exit 0
        r = wsg("replay", str(pcap), "--to", fresh.url)
        assert r.returncode == 0, r.stdout + r.stderr
        assert "all replies matched" in r.stdout
    with SimThread(model="wsg32") as other:  # another model: other stroke -> other width after homing
        r = wsg("replay", str(pcap), "--to", other.url, "--json")
        assert r.returncode == 1
        report = json.loads(r.stdout)
        assert report["matched"] is False
        assert any(d["what"] == "width" for d in report["differences"])
    with SimThread() as fresh:  # a block in the way: the move fails with another status code
        # at 52 mm, below the fingers at power-up (55 mm): homing opens away from it, the move to 50 mm
        # runs into it (homing into an obstacle would only set a wrong reference, 000 §3.2.1)
        fresh.world.block(52.0)
        r = wsg("replay", str(pcap), "--to", fresh.url)
        assert r.returncode == 1 and "status" in r.stdout


def test_replay_reads_json_lines_and_rejects_junk(sim: SimThread, tmp_path: Path) -> None:
    log = tmp_path / "s.jsonl"
    proxy = ProxyProc(sim.url, "--jsonl", str(log), "-q")
    with Gripper(f"tcp://127.0.0.1:{proxy.port}") as g:
        g.width()
    proxy.stop()
    r = wsg("replay", str(log), "--to", sim.url, "--json")
    assert r.returncode == 0 and json.loads(r.stdout)["steps"] >= 1
    junk = tmp_path / "junk.txt"
    junk.write_text("hello\n")
    r = wsg("replay", str(junk), "--to", sim.url)
    assert r.returncode == 2 and "not a JSON line" in r.stderr


def test_replay_reconnects_after_a_recorded_disconnect(sim: SimThread, tmp_path: Path) -> None:
    """000 §3.1.2: after 07h "New commands may be sent only after regular disconnection and
    reconnection", and an announced close raises no FAST STOP. Replay closes and reconnects there, so
    a recorded client that did the same matches; one that kept sending on the announced connection
    (recorded E_ACCESS_DENIED) is reported as a difference (docs/fidelity.md)."""
    from pywsg.testing.replay import replay

    width = Frame(Command.GET_OPENING_WIDTH, b"\x00\x00\x00").encode()
    bye = Frame(Command.DISCONNECT).encode()
    polite, rude = tmp_path / "polite.jsonl", tmp_path / "rude.jsonl"
    proxy = ProxyProc(sim.url, "--jsonl", str(polite), "-q")
    _raw_exchange(proxy.port, [width, bye])
    _raw_exchange(proxy.port, [width, Frame(Command.GET_SYSTEM_STATE, b"\x00\x00\x00").encode()])
    proxy.stop()
    proxy = ProxyProc(sim.url, "--jsonl", str(rude), "-q")
    _raw_exchange(proxy.port, [width, bye, width])   # the third is refused: E_ACCESS_DENIED
    proxy.stop()
    with SimThread() as fresh:
        report = replay(polite, fresh.url)
        # step 4 (40h) matched the recorded flags: no SF_FAST_STOP after the announced close
        assert report.steps == 4 and report.matched, report.differences
        report = replay(rude, fresh.url)
        assert [(d.step, d.what) for d in report.differences] == [(3, "status")]


def test_decode_reads_the_proxys_json_lines(sim: SimThread, tmp_path: Path) -> None:
    """Issue 14 item 4: the exchange file `wsg proxy` writes as JSON lines is one `wsg decode -f` reads
    (both --jsonl and the --json lines on stdout)."""
    log = tmp_path / "cell.jsonl"
    proxy = ProxyProc(sim.url, "--jsonl", str(log), "--json")
    with Gripper(f"tcp://127.0.0.1:{proxy.port}") as g:
        g.home()
        g.width()
    out, _ = proxy.stop()
    stdout_log = tmp_path / "stdout.jsonl"
    stdout_log.write_text(out)
    for path in (log, stdout_log):
        r = wsg("decode", "-f", str(path), "--json")
        assert r.returncode == 0, r.stderr
        frames = json.loads(r.stdout)
        seen = [(f["log_direction"], f["direction"], f["command"], f["status"]) for f in frames]
        homing = seen.index(("tx", "request", "HOMING", None))
        assert seen[homing + 1:homing + 3] == [("rx", "reply", "HOMING", "E_CMD_PENDING"),   # 000 §3.2.1
                                               ("rx", "reply", "HOMING", "E_SUCCESS")]
        width = next(f for f in frames if f["command"] == "GET_OPENING_WIDTH" and f["direction"] == "reply")
        assert width["params"]["width"] == pytest.approx(110.0) and width["checksum_ok"] is True
    text = wsg("decode", "-f", str(log))
    assert text.returncode == 0, text.stderr
    assert " TX (client -> gripper)" in text.stdout and "reply HOMING (20h)" in text.stdout
    assert "not a hex byte" not in text.stderr
    bad = tmp_path / "bad.jsonl"
    bad.write_text(log.read_text().splitlines()[0] + "\n{oops\n")
    r = wsg("decode", "-f", str(bad))
    assert r.returncode == 1 and f"error: {bad}: line 2: not a JSON object" in r.stderr, r.stderr
    assert "Traceback" not in r.stderr


def test_proxy_names_the_option_whose_file_cannot_be_written(sim: SimThread, tmp_path: Path) -> None:
    for option in ("--pcap", "--jsonl"):
        r = wsg("proxy", "--listen", "0", "--to", sim.url, option, str(tmp_path / "no" / "such" / "x"))
        assert r.returncode == 2 and f"Invalid value for {option}: cannot write" in r.stderr, r.stderr
        assert "--to" not in r.stderr and "Traceback" not in r.stderr
