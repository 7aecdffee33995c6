"""Transport benchmark: `wsg sim` against a bare asyncio server doing the same I/O, same run.

1. Round trips of a 41h Get Gripper State request (11-byte frame each way) from a blocking raw-socket
   client, over TCP and UDP: round trips/s, p50/p99 latency, and the ratio to a bare asyncio echo
   server answering with a reply of the same size. Both servers run for the whole part; ``--rounds``
   rounds alternate between them (sim then bare, bare then sim, ...), and the **median of the
   per-round ratios** is reported (each ratio compares two measurements seconds apart, so a shared
   machine's slow drifts in load cancel out), with the spread of the ratios.
2. Auto-update timing: N virtual grippers x 4 streams at 10 ms (40h, 41h, 43h, 44h) in one `wsg sim`
   process, one TCP connection per gripper, received by a separate process: interval error
   |gap - 10 ms| per stream (p50/p99/max) and the server's CPU, beside a bare asyncio server writing
   the same frames on the same number of connections with one `asyncio.sleep` loop per stream. Rounds
   alternate between the two as in part 1; the round with the median p99 of each is printed.

3. Capacity: the largest stream count (4 streams per connection) that still holds p99 <= 2 ms, found by
   bisection for `wsg sim` and for the bare loop, and their ratio (target >= 0.7). Robust on a noisy
   machine: each probe is the median p99 of ``--probes`` short runs; and the limit is first checked
   against the machine itself - when even the bare loop at 1 connection x 4 streams (its noise floor)
   cannot hold 2 ms, the limit becomes twice that floor and the output says so, instead of a ratio of
   "inf" from a bare capacity of 0.

Servers run in their own processes (the client does not share their GIL). Both are run on stock
asyncio and, when installed, on uvloop.

CAN (``--can``): round trips of the same 41h request over python-can's ``virtual`` bus (the inferred
mapping of docs/sim.md: 8-byte CAN frames, requests on 01h, replies on 02h), the sim in a thread of
this process (a virtual bus does not cross processes), beside TCP, UDP and serial (a pty) to the same
sim in the same conditions: a raw python-can client, ``Gripper`` and ``AsyncGripper``.

    .venv/bin/python benchmarks/bench_transport.py [--parts 1,2,3] [--counts 1,50,200] [--seconds 3]
        [--rounds 10] [--timing-rounds 3] [--loops asyncio,uvloop] [--search-seconds 2] [--probes 3]
        [--can [--can-round-trips 3000]]
"""

from __future__ import annotations

import argparse
import os
import selectors
import socket
import statistics
import subprocess
import sys
import textwrap
import time
from collections.abc import Callable

import psutil

from pywsg.protocol import CATALOG, Frame

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))  # the checkout, for tests/
from tests.ports import free_base  # ports below the ephemeral range, as the tests pick them

REQ = Frame(0x41, CATALOG[0x41].encode_request(flags=0, period_ms=0)).encode()
REPLY = Frame.reply(0x41, 0, b"\x00").encode()
assert len(REQ) == len(REPLY) == 11
STREAMS = (0x40, 0x41, 0x43, 0x44)
PY = sys.executable

BARE = textwrap.dedent(
    """
    import asyncio, sys
    mode, port, use_uv = sys.argv[1], int(sys.argv[2]), sys.argv[3] == "uvloop"
    REPLY = bytes.fromhex(sys.argv[4])
    FRAMES = [bytes.fromhex(h) for h in sys.argv[5].split(",")]

    class Echo(asyncio.Protocol):
        def connection_made(self, t):
            self.t = t
            if mode == "stream":
                loop = asyncio.get_running_loop()
                self.tasks = [loop.create_task(self.stream(f)) for f in FRAMES]
        def data_received(self, data):
            if mode == "echo":
                self.t.write(REPLY * (len(data) // 11))
        async def stream(self, frame):  # one sleep per stream, on a 10 ms grid
            loop = asyncio.get_running_loop()
            nxt = loop.time()
            while not self.t.is_closing():
                nxt += 0.010
                await asyncio.sleep(nxt - loop.time())
                self.t.write(frame)
        def connection_lost(self, exc):
            for t in getattr(self, "tasks", []):
                t.cancel()

    class UdpEcho(asyncio.DatagramProtocol):
        def connection_made(self, t):
            self.t = t
        def datagram_received(self, data, addr):
            self.t.sendto(REPLY, addr)

    async def main():
        loop = asyncio.get_running_loop()
        await loop.create_server(Echo, "127.0.0.1", port)
        if mode == "echo":
            await loop.create_datagram_endpoint(UdpEcho, local_addr=("127.0.0.1", port + 1))
        print("ready", flush=True)
        await asyncio.Event().wait()

    if use_uv:
        import uvloop
        uvloop.run(main())
    else:
        asyncio.run(main())
    """
)


def start(cmd: list[str], ready: str) -> subprocess.Popen[str]:
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    assert proc.stdout is not None
    while True:
        line = proc.stdout.readline()
        if not line:
            raise RuntimeError(f"server did not start: {cmd}")
        if ready in line:
            return proc


def stop(proc: subprocess.Popen[str]) -> None:
    proc.terminate()
    try:
        proc.wait(10)
    except subprocess.TimeoutExpired:
        proc.kill()


def sim_cmd(loop: str, base: int, count: int, udp: bool) -> list[str]:
    return [
        PY, "-c", "from pywsg.cli.main import main; main()", "sim", "--tcp-port", str(base),
        "--udp-port", str(base + count) if udp else "off", "--udp-reply-port", "0", "--serial", "off",
        "--web-port", "off", "--count", str(count), "--uvloop" if loop == "uvloop" else "--no-uvloop",
    ]


def bare_cmd(loop: str, mode: str, port: int) -> list[str]:
    frames = ",".join(Frame.reply(c, 0, b"\x00" * (1 if c == 0x41 else 4)).encode().hex() for c in STREAMS)
    return [PY, "-c", BARE, mode, str(port), loop, REPLY.hex(), frames]


# -- 1. round trips -----------------------------------------------------------------------


def connect(port: int, udp: bool) -> socket.socket:
    if udp:
        s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        s.bind(("127.0.0.1", 0))
        s.connect(("127.0.0.1", port))
    else:
        s = socket.create_connection(("127.0.0.1", port))
        s.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    s.settimeout(5)
    return s


def round_trips(s: socket.socket, n: int, warmup: int = 500) -> tuple[float, float, float]:
    """(round trips/s, p50 µs, p99 µs) of n blocking 41h round trips on ``s``."""
    lat = []
    clock = time.perf_counter_ns
    for i in range(n + warmup):
        t0 = clock()
        s.send(REQ)
        got = s.recv(64)
        while len(got) < 11:
            got += s.recv(64)
        if i >= warmup:
            lat.append(clock() - t0)
    lat.sort()
    total = sum(lat) / 1e9
    return n / total, lat[len(lat) // 2] / 1e3, lat[int(len(lat) * 0.99)] / 1e3


def bench_round_trips(loop: str, n: int, rounds: int) -> None:
    """``n`` round trips per server and interface in all, in ``rounds`` interleaved rounds."""
    base = free_base(4)
    sim = start(sim_cmd(loop, base, 1, udp=True), "UDP")
    bare = start(bare_cmd(loop, "echo", base + 2), "ready")
    per_round = max(n // rounds, 1000)
    try:
        for name, udp in (("TCP", False), ("UDP", True)):
            # one connection per server for the whole part: the sim serves one TCP client at a time
            socks = {"sim": connect(base + (1 if udp else 0), udp), "bare": connect(base + 2 + (1 if udp else 0), udp)}
            got: dict[str, list[tuple[float, float, float]]] = {"sim": [], "bare": []}
            try:
                for r in range(rounds):
                    for side in ("sim", "bare") if r % 2 == 0 else ("bare", "sim"):
                        got[side].append(round_trips(socks[side], per_round, 500 if r < 2 else 100))
            finally:
                if not udp:
                    socks["sim"].send(Frame(0x07).encode())  # announced disconnect
                for sock in socks.values():
                    sock.close()
            ratios = sorted(b[0] / s_[0] for s_, b in zip(got["sim"], got["bare"], strict=True))
            p50_ratios = sorted(s_[1] / b[1] for s_, b in zip(got["sim"], got["bare"], strict=True))
            med = {side: tuple(statistics.median(x[i] for x in got[side]) for i in range(3)) for side in got}
            rs, p50s, p99s = med["sim"]
            rb, p50b, p99b = med["bare"]
            print(
                f"  {loop:8s} {name}: wsg sim {rs:8.0f}/s p50 {p50s:6.1f} µs p99 {p99s:6.1f} µs | "
                f"bare echo {rb:8.0f}/s p50 {p50b:6.1f} µs p99 {p99b:6.1f} µs (medians of {rounds} rounds)\n"
                f"  {'':8s} {name}: ratio bare/sim throughput, median of per-round ratios "
                f"{statistics.median(ratios):4.2f}x (rounds {ratios[0]:4.2f}-{ratios[-1]:4.2f}x), "
                f"p50 sim/bare {statistics.median(p50_ratios):4.2f}x", flush=True
            )
    finally:
        stop(sim)
        stop(bare)


# -- 2. auto-update timing ------------------------------------------------------------------


def receive_streams(socks: list[socket.socket], seconds: float, warmup: float) -> list[float]:
    """Interval errors (ms) of every stream on every socket, after ``warmup`` seconds."""
    sel = selectors.DefaultSelector()
    bufs: dict[int, bytearray] = {}
    last: dict[tuple[int, int], float] = {}
    errors: list[float] = []
    for s in socks:
        s.setblocking(False)
        sel.register(s, selectors.EVENT_READ)
        bufs[s.fileno()] = bytearray()
    t_start = time.monotonic()
    t_measure = t_start + warmup
    t_end = t_measure + seconds
    while True:
        now = time.monotonic()
        if now >= t_end:
            break
        for key, _ in sel.select(t_end - now):
            sock: socket.socket = key.fileobj  # type: ignore[assignment]
            stamp = time.monotonic()
            fd = sock.fileno()
            buf = bufs[fd]
            buf += sock.recv(1 << 16)
            pos, n = 0, len(buf)
            while n - pos >= 8:
                size = buf[pos + 4] | (buf[pos + 5] << 8)
                end = pos + size + 8
                if end > n:
                    break
                k = (fd, buf[pos + 3])
                prev = last.get(k)
                if prev is not None and stamp >= t_measure:
                    errors.append(abs(stamp - prev - 0.010) * 1000)
                last[k] = stamp
                pos = end
            del buf[:pos]
    sel.close()
    return errors


def subscribe(s: socket.socket) -> None:
    for cid in STREAMS:
        s.sendall(Frame(cid, CATALOG[cid].encode_request(flags=1, period_ms=10)).encode())


def stats(errors: list[float]) -> str:
    if not errors:
        return "no packets"
    e = sorted(errors)
    return f"p50 {e[len(e) // 2]:5.2f} p99 {e[int(len(e) * 0.99)]:6.2f} max {e[-1]:6.1f} ms"


def timing_run(loop: str, count: int, seconds: float, side: str) -> tuple[str, float, float, float]:
    """One run of one side: (stats line, CPU %, packets/s, p99 ms; inf when it fell behind)."""
    warmup = 0.5
    base = free_base(count + 1)
    if side == "wsg sim":
        proc = start(sim_cmd(loop, base, count, udp=False), f"gripper {count - 1}: TCP")
        socks = [socket.create_connection(("127.0.0.1", base + i)) for i in range(count)]
        for s in socks:
            subscribe(s)
    else:
        proc = start(bare_cmd(loop, "stream", base), "ready")
        socks = [socket.create_connection(("127.0.0.1", base)) for _ in range(count)]
    try:
        ps = psutil.Process(proc.pid)
        time.sleep(0.05)
        cpu0 = sum(ps.cpu_times()[:2])
        t0 = time.monotonic()
        errors = receive_streams(socks, seconds, warmup)
        cpu = (sum(ps.cpu_times()[:2]) - cpu0) / (time.monotonic() - t0) * 100
    finally:
        for s in socks:
            s.close()
        stop(proc)
    rate = len(errors) / seconds
    expected = count * 4 * 100  # packets/s at 10 ms
    p99 = sorted(errors)[int(len(errors) * 0.99)] if errors else float("inf")
    if rate < 0.95 * expected:
        p99 = float("inf")  # falling behind (packets skipped) counts as failing
    return stats(errors), cpu, rate, p99


def bench_timing(loop: str, count: int, seconds: float, sides: tuple[str, ...] = ("wsg sim", "bare"),
                 quiet: bool = False, rounds: int = 1) -> dict[str, tuple[str, float, float, float]]:
    """Per side, the run with the median p99 of ``rounds`` runs, the sides alternating:
    (stats line, CPU %, packets/s, p99 ms)."""
    runs: dict[str, list[tuple[str, float, float, float]]] = {side: [] for side in sides}
    for r in range(rounds):
        for side in sides if r % 2 == 0 else tuple(reversed(sides)):
            runs[side].append(timing_run(loop, count, seconds, side))
    results = {side: sorted(rs, key=lambda x: x[3])[len(rs) // 2] for side, rs in runs.items()}
    if not quiet:
        for name, (st, cpu, rate, _) in results.items():
            print(f"  {loop:8s} {count:4d} x 4 streams  {name:8s} {st}  CPU {cpu:5.1f} %  {rate:8.0f} packets/s"
                  + (f"  (median-p99 run of {rounds})" if rounds > 1 else ""), flush=True)
    return results


def capacity(loop: str, side: str, seconds: float, limit_ms: float, probes: int, start: int = 25,
             top: int = 1000) -> int:
    """Largest connection count (x 4 streams) whose median p99 over ``probes`` runs is <= limit_ms:
    doubling or halving from ``start`` to bracket it, then bisection to within ~1/8."""
    def ok(n: int) -> bool:
        r = bench_timing(loop, n, seconds, (side,), quiet=True, rounds=probes)[side]
        print(f"    {loop:8s} {side:8s} {n:4d} x 4 = {4 * n:5d} streams: {r[0]}  CPU {r[1]:5.1f} %  "
              f"{'ok' if r[3] <= limit_ms else 'over' if r[3] != float('inf') else 'over (fell behind)'}", flush=True)
        return r[3] <= limit_ms

    if ok(start):
        lo, hi = start, start * 2
        while hi <= top and ok(hi):
            lo, hi = hi, hi * 2
        if hi > top:
            return lo
    else:
        lo, hi = start // 2, start
        while lo >= 1 and not ok(lo):
            lo, hi = lo // 2, lo
        if lo < 1:
            return 0
    while hi - lo > max(lo // 8, 1):
        mid = (lo + hi) // 2
        if ok(mid):
            lo = mid
        else:
            hi = mid
    return lo


def bench_capacity(loop: str, seconds: float, probes: int, limit_ms: float = 2.0) -> None:
    # the machine's own floor: both servers at 1 connection x 4 streams, alternating, median p99 of each
    floor = bench_timing(loop, 1, seconds, ("bare", "wsg sim"), quiet=True, rounds=probes)
    floor_ms = floor["bare"][3]
    print(f"    {loop:8s} noise floor at 1 x 4 streams (median p99 of {probes}): bare {floor_ms:.2f} ms, "
          f"wsg sim {floor['wsg sim'][3]:.2f} ms", flush=True)
    if floor_ms > limit_ms:
        limit_ms = 2 * floor_ms
        print(f"    {loop:8s} the bare loop cannot hold 2 ms on this machine now: limit raised to twice its "
              f"floor, {limit_ms:.2f} ms (compare the ratio, not the counts, with quiet runs)", flush=True)
    sim = capacity(loop, "wsg sim", seconds, limit_ms, probes)
    bare = capacity(loop, "bare", seconds, limit_ms, probes)
    ratio = f"{sim / bare:.2f}" if bare else "n/a (the bare loop holds no stream count)"
    print(f"  {loop:8s} largest stream count with p99 <= {limit_ms:.2f} ms: wsg sim {4 * sim}, bare {4 * bare}, "
          f"ratio {ratio} (target >= 0.7)", flush=True)


# -- CAN ---------------------------------------------------------------------------------


def _lat_stats(lat: list[int]) -> str:
    lat.sort()
    rate = len(lat) / (sum(lat) / 1e9)
    return f"{rate:8.0f}/s p50 {lat[len(lat) // 2] / 1e3:7.1f} µs p99 {lat[int(len(lat) * 0.99)] / 1e3:7.1f} µs"


def _timed_calls(fn: Callable[[], object], n: int) -> list[int]:
    clock = time.perf_counter_ns
    for _ in range(200):
        fn()
    lat = []
    for _ in range(n):
        t0 = clock()
        fn()
        lat.append(clock() - t0)
    return lat


def bench_can(n: int) -> None:
    import asyncio
    import threading
    import uuid

    import can

    from pywsg import AsyncGripper, Gripper
    from pywsg.protocol import FrameParser
    from pywsg.server import SimOptions, SimServer

    channel = f"bench-{uuid.uuid4().hex[:8]}"
    loop = asyncio.new_event_loop()
    threading.Thread(target=loop.run_forever, daemon=True).start()
    sim = SimServer(SimOptions(tcp_port=0, udp_port=0, udp_reply_port=None, serial="pty", web_port=None,
                               can_channel=channel))
    asyncio.run_coroutine_threadsafe(sim.start(), loop).result(10)
    urls = {"CAN": f"can://{channel}?interface=virtual", "TCP": str(sim.grippers[0].tcp_url),
            "UDP": f"udp://127.0.0.1:{sim.udp_port}?reply_port=0", "serial": str(sim.grippers[0].serial_url)}
    try:
        bus = can.Bus(interface="virtual", channel=channel,
                      can_filters=[{"can_id": 0x02, "can_mask": 0x7FF, "extended": False}])
        msgs = [can.Message(arbitration_id=0x01, data=REQ[i:i + 8], is_extended_id=False)
                for i in range(0, len(REQ), 8)]
        parser = FrameParser()

        def raw() -> None:
            for m in msgs:
                bus.send(m)
            while True:
                msg = bus.recv(5)
                assert msg is not None, "no reply"
                if parser.feed(bytes(msg.data)):
                    return

        print(f"  raw python-can client, CAN       {_lat_stats(_timed_calls(raw, n))}")
        bus.shutdown()
        for name, url in urls.items():
            with Gripper(url, timeout=5) as g:
                print(f"  Gripper.gripper_state(), {name:<6}      {_lat_stats(_timed_calls(g.gripper_state, n))}")

        async def aio(url: str) -> list[int]:
            async with AsyncGripper(url, timeout=5) as g:
                for _ in range(200):
                    await g.gripper_state()
                lat = []
                clock = time.perf_counter_ns
                for _ in range(n):
                    t0 = clock()
                    await g.gripper_state()
                    lat.append(clock() - t0)
                return lat

        for name, url in urls.items():
            print(f"  AsyncGripper.gripper_state(), {name:<6} {_lat_stats(asyncio.run(aio(url)))}")
    finally:
        asyncio.run_coroutine_threadsafe(sim.close(save=False), loop).result(10)
        loop.call_soon_threadsafe(loop.stop)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--counts", default="1,50,200", help="gripper counts for the timing test")
    ap.add_argument("--seconds", type=float, default=3.0, help="measuring time per timing run")
    ap.add_argument("--round-trips", type=int, default=20000, help="round trips per server and interface, in all")
    ap.add_argument("--rounds", type=int, default=10, help="interleaved rounds of part 1")
    ap.add_argument("--timing-rounds", type=int, default=3, help="interleaved runs per count in part 2")
    ap.add_argument("--probes", type=int, default=3, help="runs per probe of the capacity search (median p99)")
    ap.add_argument("--parts", default="1,2,3", help="1 round trips, 2 timing, 3 capacity search")
    ap.add_argument("--search-seconds", type=float, default=2.0, help="measuring time per search probe")
    loops = ["asyncio"]
    try:
        import uvloop  # noqa: F401

        loops.append("uvloop")
    except ImportError:
        pass
    ap.add_argument("--loops", default=",".join(loops))
    ap.add_argument("--can", action="store_true", help="only the CAN round trips (python-can virtual bus)")
    ap.add_argument("--can-round-trips", type=int, default=3000)
    args = ap.parse_args()
    load = os.getloadavg()[0]
    print(f"machine: {os.cpu_count()} cores, load average {load:.2f} at start, Python {sys.version.split()[0]}")
    parts = args.parts.split(",")
    if args.can:
        print(f"CAN round trips of a 41h request, {args.can_round_trips} each, sim in this process "
              "(python-can virtual bus; TCP/UDP/serial pty to the same sim for comparison)")
        bench_can(args.can_round_trips)
        parts = []
    if "1" in parts:
        print("1. round trips of a 41h request (blocking raw-socket client)")
        for loop in args.loops.split(","):
            bench_round_trips(loop, args.round_trips, args.rounds)
    if "2" in parts:
        print("2. auto-update interval error seen by a receiving client (10 ms period)")
        for loop in args.loops.split(","):
            for count in (int(c) for c in args.counts.split(",")):
                bench_timing(loop, count, args.seconds, rounds=args.timing_rounds)
    if "3" in parts:
        print("3. largest stream count holding p99 <= 2 ms (bisection; 10 ms period, 4 streams per connection)")
        for loop in args.loops.split(","):
            bench_capacity(loop, args.search_seconds, args.probes)
    print(f"load average {os.getloadavg()[0]:.2f} at the end")


if __name__ == "__main__":
    main()
