"""CLI figures: start-up time of `wsg`, a driver round trip through `wsg info`, capture decoding speed.

Run: .venv/bin/python benchmarks/cli_bench.py   (starts its own `wsg sim` on free ports)
"""

from __future__ import annotations

import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import dpkt

from pywsg.capture.reader import frames_from_capture
from pywsg.protocol import Frame, Status
from pywsg.protocol.editor import parse_payload

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the checkout, for tests/
from tests.ports import free_port  # ports below the ephemeral range, as the tests pick them

WSG = str(Path(sys.executable).with_name("wsg"))


def wall(argv: list[str], n: int = 8) -> float:
    times = []
    for _ in range(n):
        t = time.perf_counter()
        subprocess.run(argv, capture_output=True, check=False)
        times.append(time.perf_counter() - t)
    return statistics.median(times)


def capture_speed(n: int) -> tuple[float, int]:
    req = Frame(0x43, b"\x00\x00\x00").encode()
    rep = Frame.reply(0x43, Status.E_SUCCESS, b"\x00\x00\x48\x42").encode()
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "big.pcap"
        with path.open("wb") as f:
            w = dpkt.pcap.Writer(f)
            cseq, sseq = 1, 1
            for i in range(n):
                for src, dst, sp, dp, data, seq in ((b"\x7f\0\0\1", b"\x7f\0\0\2", 40000, 1000, req, cseq),
                                                    (b"\x7f\0\0\2", b"\x7f\0\0\1", 1000, 40000, rep, sseq)):
                    t = dpkt.tcp.TCP(sport=sp, dport=dp, seq=seq, flags=dpkt.tcp.TH_ACK, data=data)
                    ip = dpkt.ip.IP(src=src, dst=dst, p=6, data=t)
                    ip.len = len(bytes(ip))
                    w.writepkt(bytes(dpkt.ethernet.Ethernet(type=0x0800, data=ip)), i * 0.001)
                cseq += len(req)
                sseq += len(rep)
        t0 = time.perf_counter()
        frames = frames_from_capture(path)
        dt = time.perf_counter() - t0
    return len(frames) / dt, len(frames)


def main() -> None:
    print(f"wsg --help: {wall([WSG, '--help']) * 1000:.0f} ms (median of 8)")
    print(f"wsg send --dry-run 1: {wall([WSG, 'send', '--dry-run', '1']) * 1000:.0f} ms")
    port = free_port()
    sim = subprocess.Popen([WSG, "sim", "--no-uvloop", "--tcp-port", str(port), "--udp-port", "0", "--serial", "off",
                            "--web-port", "0"], stdout=subprocess.PIPE, text=True)
    assert sim.stdout is not None
    sim.stdout.readline()
    try:
        url = f"tcp://127.0.0.1:{port}"
        print(f"wsg info (connect, 50h, 07h, exit): {wall([WSG, '--url', url, 'info']) * 1000:.0f} ms")
        print(f"wsg send 0x50 (raw link): {wall([WSG, '--url', url, 'send', '0x50']) * 1000:.0f} ms")
    finally:
        sim.terminate()
        sim.wait()
    rate, count = capture_speed(20000)
    print(f"capture decoding (TCP, Ethernet pcap, {count} frames): {rate:,.0f} frames/s")
    items = "0x20 32 150.0f " + '"ack" ' + "1000u16 " * 4
    t0 = time.perf_counter()
    for _ in range(20000):
        parse_payload(items)
    print(f"editor syntax: {20000 / (time.perf_counter() - t0):,.0f} payload lines/s (9 items each)")


if __name__ == "__main__":
    main()
