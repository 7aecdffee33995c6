"""PROFIBUS DP figures: the slave's response time (TSDR) on a real serial port's code path, per declared
baud rate and event loop, beside a bare responder on the same path and what WEIS5555.gsd declares.

The path is a socat pty pair (``socat pty,raw,echo=0,link=A pty,raw,echo=0,link=B``): ``wsg sim
--profibus A --profibus-baudrate R`` opens A as a serial device (pyserial, 8E1, parity checking, the
code of a USB RS-485 adapter); a minimal master in this process writes to B. The slave is
parameterised with the smallest min TSDR (11 bit times, the standard's floor), then answers
Data_Exchange requests; the master times just before its write → the response's first byte. That is
TSDR plus the two pty hops (the bare responder's figure: a 10-line Python select loop that answers
each request at once). An answer the slave could not start within the GSD's MaxTsdr is not sent
(the master repeats the request after its slot time, here 50 ms): "lost" counts those.
With ``--hogs 2`` two ``yes >/dev/null`` run meanwhile (killed at the end).

    .venv/bin/python benchmarks/bench_profibus.py [--requests 1000] [--hogs 2] [--rates 45450,1500000]
"""

from __future__ import annotations

import argparse
import contextlib
import math
import os
import select
import signal
import statistics
import subprocess
import sys
import tempfile
import time
import tty
from collections.abc import Iterator
from pathlib import Path

from pywsg.fieldbus.profibus import fdl
from pywsg.fieldbus.profibus.gsd import baud_key, facts

MASTER, SLAVE = 2, 7
SLOT_S = 0.05          # the benchmark master's slot time: repeat an unanswered request after it
MARGIN = 2.0           # proposed MaxTsdr = MARGIN × the worst p99 over the loops

BARE = r"""
import os, select, sys, tty
fd = os.open(sys.argv[1], os.O_RDWR | os.O_NOCTTY); tty.setraw(fd)
print("ready", flush=True)
while True:
    select.select([fd], [], [])
    data = os.read(fd, 512)
    if data:
        os.write(fd, b"\xe5")
"""


@contextlib.contextmanager
def socat_pair() -> Iterator[tuple[str, str]]:
    with tempfile.TemporaryDirectory() as tmp:
        a, b = Path(tmp) / "slave", Path(tmp) / "master"
        proc = subprocess.Popen(["socat", f"pty,raw,echo=0,link={a}", f"pty,raw,echo=0,link={b}"])
        try:
            while not (a.exists() and b.exists()):
                time.sleep(0.01)
            yield str(a), str(b)
        finally:
            proc.terminate()
            proc.wait(10)


@contextlib.contextmanager
def hogs(n: int) -> Iterator[None]:
    procs = [subprocess.Popen(["yes"], stdout=subprocess.DEVNULL) for _ in range(n)]
    try:
        yield
    finally:
        for p in procs:
            p.kill()
            p.wait()


@contextlib.contextmanager
def responder(cmd: list[str], ready: str) -> Iterator[None]:
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, text=True, env=dict(os.environ, PYTHONUNBUFFERED="1"))
    assert proc.stdout is not None
    while ready not in proc.stdout.readline():
        if proc.poll() is not None:
            raise SystemExit(f"{' '.join(cmd)} did not start")
    try:
        yield
    finally:
        proc.send_signal(signal.SIGTERM)
        try:
            proc.wait(10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


def sim_cmd(path: str, rate: int, loop: str, rt: bool) -> list[str]:
    return (["chrt", "-f", "20"] if rt else []) + [
        sys.executable, "-c", "from pywsg.cli.main import main; main()", "sim", "--tcp-port", "off",
        "--udp-port", "off", "--serial", "off", "--web-port", "off", "--profibus", path,
        "--profibus-baudrate", str(rate), "--uvloop" if loop == "uvloop" else "--no-uvloop"]


def first_byte(fd: int, request: bytes) -> float | None:
    """Seconds from just before the write to the answer's first byte; None after SLOT_S. The rest of
    the answer is read and dropped."""
    t0 = time.perf_counter()
    os.write(fd, request)
    ready, _, _ = select.select([fd], [], [], SLOT_S)
    t1 = time.perf_counter()
    if not ready:
        return None
    time.sleep(0.0005)
    with contextlib.suppress(BlockingIOError):
        os.read(fd, 512)
    return t1 - t0


def drain(fd: int) -> None:
    while select.select([fd], [], [], 0.01)[0]:
        with contextlib.suppress(BlockingIOError):
            os.read(fd, 4096)


def measure(fd: int, requests: list[bytes], n: int) -> tuple[list[float], int]:
    """(response times of ``n`` answered requests cycling through ``requests``, requests lost)."""
    times: list[float] = []
    lost = 0
    i = 0
    while len(times) < n:
        t = first_byte(fd, requests[i % len(requests)])
        if t is None:
            lost += 1
            drain(fd)
            if lost > n:
                raise SystemExit("the slave does not answer")
            continue                     # the same request again (same FCB): a DP master's retry
        times.append(t)
        i += 1
    return times, lost


def slave_requests() -> tuple[list[bytes], list[bytes]]:
    prm = bytes((0x80, 0, 0, 11, 0x55, 0x55, 0))       # lock, no watchdog, min TSDR 11 bit times
    setup = [fdl.encode(SLAVE, MASTER, 0x5D, prm, 61, 62), fdl.encode(SLAVE, MASTER, 0x7D, b"\xa7\x9b", 62, 62)]
    exch = [fdl.encode(SLAVE, MASTER, 0x5D | (0x20 * (i % 2)), bytes((0, i & 0xFF, 0, 0, 0, 0, 0, 0)))
            for i in range(256)]
    return setup, exch


def open_master(path: str) -> int:
    fd = os.open(path, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
    tty.setraw(fd)
    return fd


def quantiles(times: list[float]) -> tuple[float, float, float]:
    q = statistics.quantiles(times, n=100)
    return q[49], q[98], max(times)


def main() -> None:
    ap = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    ap.add_argument("--requests", type=int, default=1000, help="answered requests per rate and loop")
    ap.add_argument("--hogs", type=int, default=0, help="CPU hogs (yes >/dev/null) while measuring")
    ap.add_argument("--rates", default="", help="comma-separated bit/s (default: all the GSD declares)")
    ap.add_argument("--loops", default="uvloop,asyncio")
    ap.add_argument("--chrt", action="store_true", help="run the slave with SCHED_FIFO priority 20 (chrt -f 20)")
    args = ap.parse_args()
    gsd = facts()
    rates = [int(r) for r in args.rates.split(",")] if args.rates else list(gsd.baud_rates)
    loops = args.loops.split(",")
    print(f"PROFIBUS DP slave response time on a socat pty pair, {args.requests} answered Data_Exchange "
          f"requests per rate and loop, {args.hogs} CPU hog(s); {os.cpu_count()} CPUs; slave "
          + ("SCHED_FIFO 20 (chrt -f 20)" if args.chrt else "at normal priority"))
    print(f"load average at start: {' '.join(f'{x:.1f}' for x in os.getloadavg())}")
    worst: dict[int, float] = {}
    with hogs(args.hogs):
        if args.chrt:
            # The line (socat stands in for the kernel's UART driver), the bare responder and this
            # master run at real-time priority too, so that the figures are the slave's own; the hogs
            # were started before, at normal priority.
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(20))
        run(args, rates, loops, worst)
    print(f"load average at end: {' '.join(f'{x:.1f}' for x in os.getloadavg())}")
    print(f"proposed MaxTsdr ({MARGIN:g} x the worse loop's p99, in bit times, rounded up to 10):")
    for rate, p99 in worst.items():
        bits = math.ceil(MARGIN * p99 * rate / 10) * 10
        print(f"  MaxTsdr_{baud_key(rate):<6} = {bits:>5}   ({bits / rate * 1e3:.2f} ms; declared "
              f"{gsd.max_tsdr.get(rate, 0)})")


def run(args: argparse.Namespace, rates: list[int], loops: list[str], worst: dict[int, float]) -> None:
    """Measure the bare responder, then the slave at each rate on each loop; fill ``worst`` (p99 s)."""
    gsd = facts()
    setup, exch = slave_requests()
    with socat_pair() as (slave_path, master_path):
        with responder([sys.executable, "-c", BARE, slave_path], "ready"):
            fd = open_master(master_path)
            try:
                bare, _ = measure(fd, [b"\x10\x07\x02\x49\x52\x16"], args.requests)
            finally:
                os.close(fd)
        b50, b99, bmax = quantiles(bare)
        print(f"bare responder (no slave logic, same path): p50 {b50 * 1e3:.3f} ms  p99 {b99 * 1e3:.3f} ms  "
              f"max {bmax * 1e3:.3f} ms")
        print(f"{'rate':>9} {'loop':<8} {'p50 ms':>8} {'p99 ms':>8} {'max ms':>8} {'p99 bit':>8} "
              f"{'lost':>5} {'MaxTsdr':>8}")
        for rate in rates:
            for loop in loops:
                with responder(sim_cmd(slave_path, rate, loop, args.chrt), "PROFIBUS"):
                    fd = open_master(master_path)
                    try:
                        drain(fd)
                        for req in setup:
                            measure(fd, [req], 1)
                        times, lost = measure(fd, exch, args.requests)
                    finally:
                        os.close(fd)
                p50, p99, mx = quantiles(times)
                worst[rate] = max(worst.get(rate, 0.0), p99)
                print(f"{rate:>9} {loop:<8} {p50 * 1e3:8.3f} {p99 * 1e3:8.3f} {mx * 1e3:8.2f} "
                      f"{p99 * rate:8.0f} {lost:>5} {gsd.max_tsdr.get(rate, 0):>8}", flush=True)


if __name__ == "__main__":
    main()
