"""PROFIBUS DP figures: the slave's response time (TSDR) beside what WEIS5555.gsd declares, and
Data_Exchange cycles/s with pyprofibus as the master.

The slave is a real ``wsg sim --profibus pty`` process. The response time is measured by a minimal
master in this process that writes one Data_Exchange request to the pty and waits (``select``) for
the first byte of the response: end of request → start of response, as TSDR is defined, plus the
kernel's pty hop both ways. On a real RS-485 line the request also takes its transmission time, which
the TSDR does not count, and a USB adapter adds its own latency (an FTDI chip buffers up to 1 ms
by default: ``setserial /dev/ttyUSB0 low_latency``).

    .venv/bin/python benchmarks/bench_profibus.py [--requests 3000] [--seconds 3]
"""

from __future__ import annotations

import argparse
import os
import select
import signal
import statistics
import subprocess
import sys
import time
import tty

from pywsg.fieldbus.profibus import fdl
from pywsg.fieldbus.profibus.gsd import facts

MASTER, SLAVE = 2, 7


def start_sim() -> tuple[subprocess.Popen[str], str]:
    proc = subprocess.Popen(
        [sys.executable, "-c", "from pywsg.cli.main import main; main()", "sim", "--tcp-port", "off",
         "--udp-port", "off", "--serial", "off", "--web-port", "off", "--profibus", "pty"],
        stdout=subprocess.PIPE, text=True, env=dict(os.environ, PYTHONUNBUFFERED="1"))
    assert proc.stdout is not None
    line = proc.stdout.readline()
    path = line.split("profibus://", 1)[1].split("?", 1)[0]
    return proc, path


def exchange(fd: int, request: bytes, timeout: float = 1.0) -> tuple[float, bytes]:
    """(seconds from the request written to the first response byte, the whole response)."""
    os.write(fd, request)
    t0 = time.perf_counter()
    ready, _, _ = select.select([fd], [], [], timeout)
    t1 = time.perf_counter()
    if not ready:
        raise TimeoutError("no response")
    data = os.read(fd, 512)
    parser = fdl.FdlParser()
    events = parser.feed(data)
    while not events and data != fdl.SHORT_ACK:
        data += os.read(fd, 512)
        events = parser.feed(data[-512:])
    return t1 - t0, data


def response_times(path: str, n: int) -> list[float]:
    fd = os.open(path, os.O_RDWR | os.O_NOCTTY)
    tty.setraw(fd)
    try:
        fcb = 0x20
        prm = bytes((0x80, 0, 0, 0, 0x55, 0x55, 0))
        for dsap, data in ((61, prm), (62, bytes((0xA7, 0x9B)))):
            _, resp = exchange(fd, fdl.encode(SLAVE, MASTER, 0x4D | fcb | 0x10, data, dsap, 62))
            assert resp == fdl.SHORT_ACK, resp
            fcb ^= 0x20
        out: list[float] = []
        for i in range(n):
            dt, _ = exchange(fd, fdl.encode(SLAVE, MASTER, 0x4D | fcb | 0x10, bytes((0, i & 0xFF, 0, 0, 0, 0, 0, 0))))
            fcb ^= 0x20
            out.append(dt)
        return out
    finally:
        os.close(fd)


def pyprofibus_cycles(path: str, seconds: float) -> float:
    import io
    from importlib import resources

    import pyprofibus

    gsd = resources.files("pywsg.fieldbus") / "descriptions" / "WEIS5555.gsd"
    conf = pyprofibus.PbConf(io.StringIO(f"""
[PHY]
type = serial
dev = {path}
baud = 19200
[DP]
master_addr = {MASTER}
[SLAVE_0]
addr = {SLAVE}
gsd = {gsd}
input_size = 8
output_size = 12
watchdog_ms = 1000
"""))
    master = conf.makeDPM()
    desc = conf.slaveConfs[0].makeDpSlaveDesc()
    master.addSlave(desc)
    master.initialize()
    try:
        deadline = time.monotonic() + 10
        while not desc.isConnected() and time.monotonic() < deadline:
            desc.setMasterOutData(bytearray(8))
            master.run()
        n, t0 = 0, time.perf_counter()
        while time.perf_counter() - t0 < seconds:
            desc.setMasterOutData(bytearray(8))
            master.run()
            if desc.getMasterInData() is not None:
                n += 1
        return n / (time.perf_counter() - t0)
    finally:
        master.destroy()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--requests", type=int, default=3000)
    ap.add_argument("--seconds", type=float, default=3.0)
    args = ap.parse_args()
    proc, path = start_sim()
    try:
        times = response_times(path, args.requests)
        q = statistics.quantiles(times, n=100)
        p50, p99, worst = q[49], q[98], max(times)
        print(f"slave response time over a pty, {len(times)} Data_Exchange requests "
              f"(load average {os.getloadavg()[0]:.1f}):")
        print(f"  p50 {p50 * 1e3:.3f} ms   p99 {p99 * 1e3:.3f} ms   max {worst * 1e3:.3f} ms")
        print("  declared in WEIS5555.gsd:")
        gsd = facts()
        for rate in gsd.baud_rates:
            tsdr = gsd.max_tsdr_s(rate)
            print(f"    {rate:>7} bit/s  MaxTsdr {gsd.max_tsdr[rate]:>4} bit = {tsdr * 1e3:6.3f} ms"
                  f"   p99 margin {tsdr / p99:5.1f}x")
        print(f"Data_Exchange with pyprofibus DPM1 as master: {pyprofibus_cycles(path, args.seconds):.0f} cycles/s")
    finally:
        proc.send_signal(signal.SIGTERM)
        proc.wait(10)


if __name__ == "__main__":
    main()
