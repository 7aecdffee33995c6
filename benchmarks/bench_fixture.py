"""Test-fixture benchmark: start-up of a fresh virtual gripper per test, and the latency `wsg proxy` adds.

Run: .venv/bin/python benchmarks/bench_fixture.py [--quick]

1. Start-up: what the ``wsg_sim`` pytest fixture does per test — a fresh SimThread (TCP and UDP on
   free loopback ports) on the session's shared server thread, then stopped. Also with a private
   server thread (``with SimThread():`` outside pytest).
2. Proxy: round trips of GET_OPENING_WIDTH (43h) from a raw TCP client, directly to a sim and through
   a :class:`pywsg.testing.proxy.Proxy` on its own thread (decoded comm log written to /dev/null, and
   quiet). A round trip crosses the proxy twice (request and reply), so the added latency per frame
   is half the added round-trip time.
"""

from __future__ import annotations

import argparse
import os
import platform
import socket
import statistics
import time

from pywsg.capture.commlog import CommLog
from pywsg.protocol import CATALOG, Frame
from pywsg.testing import LoopThread, SimThread
from pywsg.testing.proxy import Proxy


def pct(values: list[float], q: float) -> float:
    s = sorted(values)
    return s[min(len(s) - 1, int(q * len(s)))]


def bench_startup(n: int) -> None:
    shared = LoopThread()
    for label, make in (("shared server thread (wsg_sim fixture)", lambda: SimThread(loop=shared)),
                        ("own server thread (with SimThread())", SimThread)):
        start, total = [], []
        for _ in range(n):
            t0 = time.perf_counter()
            sim = make().start()
            t1 = time.perf_counter()
            sim.stop()
            t2 = time.perf_counter()
            start.append((t1 - t0) * 1e3)
            total.append((t2 - t0) * 1e3)
        print(f"  {label:40s} start p50 {pct(start, .5):6.2f} ms  p90 {pct(start, .9):6.2f} ms   "
              f"start+stop p50 {pct(total, .5):6.2f} ms  p90 {pct(total, .9):6.2f} ms")
    shared.close()


def rtts(port: int, n: int) -> list[float]:
    req = Frame(0x43, CATALOG[0x43].encode_request(flags=0, period_ms=0)).encode()
    out = []
    with socket.create_connection(("127.0.0.1", port)) as s:
        s.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        for i in range(n + 50):
            t0 = time.perf_counter()
            s.sendall(req)
            got = 0
            while got < 14:  # the reply of 43h: 8 bytes frame + 6 payload
                got += len(s.recv(64))
            if i >= 50:  # warm-up
                out.append((time.perf_counter() - t0) * 1e6)
        s.sendall(Frame(0x07).encode())
        s.recv(64)
    return out


def bench_proxy(n: int) -> None:
    with SimThread(udp_port=None) as sim:
        direct = rtts(sim.g.tcp_port or 0, n)
        base = statistics.median(direct)
        print(f"  direct to the sim                        round trip p50 {base:7.1f} µs  "
              f"p90 {pct(direct, .9):7.1f} µs")
        for label, log in (("through the proxy, decoded log", CommLog(text=open(os.devnull, "w"))),  # noqa: SIM115
                           ("through the proxy, quiet", None)):
            lt = LoopThread("proxy")
            proxy = Proxy(sim.url, 0, log=log)
            lt.run(proxy.start())
            via = rtts(proxy.port_bound, n)
            lt.run(proxy.close())
            lt.close()
            med = statistics.median(via)
            print(f"  {label:40s} round trip p50 {med:7.1f} µs  p90 {pct(via, .9):7.1f} µs  "
                  f"added per frame p50 {(med - base) / 2:6.1f} µs")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0] if __doc__ else None)
    ap.add_argument("--quick", action="store_true", help="fewer repetitions")
    args = ap.parse_args()
    print(f"Python {platform.python_version()} on {platform.machine()}, {os.cpu_count()} CPUs")
    print("Fresh virtual gripper per test (TCP + UDP on free ports):")
    bench_startup(50 if args.quick else 300)
    print("Proxy latency, GET_OPENING_WIDTH (43h) round trips on loopback:")
    bench_proxy(500 if args.quick else 3000)


if __name__ == "__main__":
    main()
