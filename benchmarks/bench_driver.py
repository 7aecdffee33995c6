"""Driver round trips against `wsg sim` on loopback, each beside a raw client of the same kind.

    .venv/bin/python benchmarks/bench_driver.py [--seconds 0.5] [--rounds 10] [--uvloop]
    .venv/bin/python benchmarks/bench_driver.py --against OLD/src   # before/after in one run

Prints, for Get Gripper State (41h):
- blocking: a raw socket client (sendall + recv of the same bytes) vs ``Gripper.gripper_state()``;
- asyncio: a raw ``BufferedProtocol`` client vs ``AsyncGripper.gripper_state()``;
round trips/s and p50/p99 latency, the ratio driver/raw (target <= 1.3x), and the added latency of a
command while 4 auto-update streams (40h, 41h, 43h, 45h) run at 10 ms. Rounds alternate between
the clients (each round runs every client once, in the same order, against the same server); the
best round and the median round of each are reported (the machine is shared), the ratios from both,
and the median of the per-round ratios (a driver compared with the raw client of the same round,
seconds apart, so slow drifts of the machine's load cancel out).

``--against DIR``: before and after in one run. The ``pywsg`` package in DIR (e.g. ``src`` of an older
checkout) is loaded beside this one as ``pywsg_before``; every round runs the raw clients and both
drivers, the order of before/after alternating, against the same sim, and the medians of the per-round
ratios driver/raw are printed for each.
"""

from __future__ import annotations

import argparse
import asyncio
import os
import socket
import statistics
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from pywsg import AsyncGripper, Gripper
from pywsg.client import calls
from pywsg.protocol import Command, encode_frame

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the checkout, for tests/
from tests.ports import free_port  # ports below the ephemeral range, as the tests pick them

REQ = encode_frame(Command.GET_GRIPPER_STATE, b"\x00\x00\x00")
REPLY_LEN = 6 + 3 + 2  # header, status + state, CRC
DISCONNECT = encode_frame(Command.DISCONNECT)
# the raw clients send exactly the bytes the drivers send for gripper_state()
assert calls.gripper_state().wire == REQ, calls.gripper_state().wire.hex()


def start_sim(port: int, uvloop: bool) -> subprocess.Popen[bytes]:
    wsg = Path(sys.executable).with_name("wsg")
    cmd = [str(wsg), "sim", "--host", "127.0.0.1", "--tcp-port", str(port), "--udp-port", "0", "--serial", "off",
           "--web-port", "0", "--uvloop" if uvloop else "--no-uvloop"]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
    assert proc.stdout is not None
    deadline = time.monotonic() + 15
    while time.monotonic() < deadline:  # wait for its "gripper 0: TCP tcp://..." line
        line = proc.stdout.readline().decode(errors="replace")
        if not line:
            break
        if "TCP" in line:
            return proc
    proc.kill()
    raise SystemExit("wsg sim did not start")


class Result:
    def __init__(self, name: str, lat: list[float], wall: float) -> None:
        self.name = name
        self.n = len(lat)
        self.rate = self.n / wall
        lat.sort()
        self.p50 = lat[len(lat) // 2] * 1e6
        self.p99 = lat[int(len(lat) * 0.99)] * 1e6

    def line(self) -> str:
        return f"{self.name:<44} {self.rate:>9,.0f} rt/s   p50 {self.p50:7.1f} µs   p99 {self.p99:7.1f} µs"


def timed(fn: Callable[[], object], seconds: float) -> tuple[list[float], float]:
    lat: list[float] = []
    pc = time.perf_counter
    t0 = pc()
    end = t0 + seconds
    while True:
        a = pc()
        fn()
        b = pc()
        lat.append(b - a)
        if b > end:
            return lat, b - t0


# ---------------------------------------------------------------- blocking
def raw_blocking(port: int, seconds: float) -> Result:
    s = socket.create_connection(("127.0.0.1", port))
    s.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)

    def once() -> None:
        s.sendall(REQ)
        got = 0
        while got < REPLY_LEN:
            got += len(s.recv(4096))

    once()
    lat, wall = timed(once, seconds)
    s.sendall(DISCONNECT)
    s.recv(64)
    s.close()
    return Result("raw blocking socket", lat, wall)


def driver_blocking(port: int, seconds: float, streams: bool = False) -> Result:
    with Gripper(f"tcp://127.0.0.1:{port}") as g:
        subs = [g.subscribe(n, 0.01) for n in ("system_state", "gripper_state", "width", "force")] if streams else []
        g.gripper_state()
        lat, wall = timed(g.gripper_state, seconds)
        for s in subs:
            s.close()
    return Result("Gripper.gripper_state()" + (" + 4 streams @10 ms" if streams else ""), lat, wall)


# ---------------------------------------------------------------- asyncio
class _RawProto(asyncio.BufferedProtocol):
    def __init__(self) -> None:
        self.buf = memoryview(bytearray(65536))
        self.got = 0
        self.fut: asyncio.Future[None] | None = None

    def get_buffer(self, sizehint: int) -> memoryview:
        return self.buf

    def buffer_updated(self, nbytes: int) -> None:
        self.got += nbytes
        if self.got >= REPLY_LEN and self.fut is not None and not self.fut.done():
            self.got -= REPLY_LEN
            self.fut.set_result(None)


async def raw_async(port: int, seconds: float) -> Result:
    loop = asyncio.get_running_loop()
    t, p = await loop.create_connection(_RawProto, "127.0.0.1", port)

    async def once() -> None:
        p.fut = loop.create_future()
        t.write(REQ)
        await p.fut

    await once()
    lat, wall = await atimed(once, seconds)
    p.fut = loop.create_future()
    t.write(DISCONNECT)
    await asyncio.sleep(0.01)
    t.close()
    return Result("raw asyncio BufferedProtocol", lat, wall)


async def atimed(fn: Callable[[], object], seconds: float) -> tuple[list[float], float]:
    lat: list[float] = []
    pc = time.perf_counter
    t0 = pc()
    end = t0 + seconds
    while True:
        a = pc()
        await fn()  # type: ignore[misc]
        b = pc()
        lat.append(b - a)
        if b > end:
            return lat, b - t0


async def driver_async(port: int, seconds: float, streams: bool = False) -> Result:
    async with AsyncGripper(f"tcp://127.0.0.1:{port}") as g:
        subs = [await g.subscribe(n, 0.01) for n in ("system_state", "gripper_state", "width", "force")] \
            if streams else []
        await g.gripper_state()
        lat, wall = await atimed(g.gripper_state, seconds)
        for s in subs:
            await s.close()
    return Result("AsyncGripper.gripper_state()" + (" + 4 streams @10 ms" if streams else ""), lat, wall)


def load_before(src: str) -> Any:
    """The pywsg package in ``src`` as a second package, ``pywsg_before`` (its imports are relative)."""
    import importlib
    import shutil
    import tempfile

    tmp = tempfile.mkdtemp(prefix="bench-driver-")
    shutil.copytree(Path(src) / "pywsg", Path(tmp) / "pywsg_before")
    sys.path.insert(0, tmp)
    return importlib.import_module("pywsg_before")


async def driver_async_of(cls: Any, port: int, seconds: float) -> Result:
    async with cls(f"tcp://127.0.0.1:{port}", timeout=10) as g:
        await g.gripper_state()
        lat, wall = await atimed(g.gripper_state, seconds)
    return Result(cls.__module__.split(".")[0], lat, wall)


def driver_blocking_of(cls: Any, port: int, seconds: float) -> Result:
    with cls(f"tcp://127.0.0.1:{port}", timeout=10) as g:
        g.gripper_state()
        lat, wall = timed(g.gripper_state, seconds)
    return Result(cls.__module__.split(".")[0], lat, wall)


def compare(port: int, args: argparse.Namespace, runner: Callable[..., Any]) -> None:
    """Before (``--against``) and after in the same rounds; each driver beside the raw client of its round."""
    import pywsg

    mods = {"before": load_before(args.against), "after": pywsg}
    ratios: dict[str, list[tuple[float, float]]] = {}
    for i in range(args.rounds):
        for name in (("before", "after") if i % 2 == 0 else ("after", "before")):
            mod = mods[name]
            for kind in ("blocking", "asyncio"):
                # a pause after each client: the sim closes the last connection before the next one comes
                if kind == "blocking":
                    r = raw_blocking(port, args.seconds)
                    time.sleep(0.05)
                    d = driver_blocking_of(mod.Gripper, port, args.seconds)
                else:
                    r = runner(raw_async(port, args.seconds))
                    time.sleep(0.05)
                    d = runner(driver_async_of(mod.AsyncGripper, port, args.seconds))
                time.sleep(0.05)
                ratios.setdefault(f"{kind} {name}", []).append((r.rate / d.rate, d.p50 / r.p50))
    print(f"# driver before ({args.against}) and after, 41h Get Gripper State, {args.rounds} rounds x "
          f"{args.seconds:g} s, before/after alternating, {os.cpu_count()} CPUs, "
          f"load average {os.getloadavg()[0]:.2f}")
    for key, v in ratios.items():
        print(f"{key:16s} raw/driver rate ratio {statistics.median(r for r, _ in v):.2f}x, "
              f"p50 ratio {statistics.median(p for _, p in v):.2f}x (medians of {len(v)} rounds)")


def best(results: list[Result]) -> Result:
    return max(results, key=lambda r: r.rate)


def median(results: list[Result]) -> Result:
    return sorted(results, key=lambda r: r.rate)[len(results) // 2]


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seconds", type=float, default=0.5)
    ap.add_argument("--rounds", type=int, default=10)
    ap.add_argument("--uvloop", action="store_true", help="run the asyncio clients on uvloop")
    ap.add_argument("--sim-uvloop", action="store_true", help="run wsg sim on uvloop (default: stock asyncio)")
    ap.add_argument("--against", default="", help="a src dir holding an older pywsg: before/after in one run")
    args = ap.parse_args()
    port = free_port()
    proc = start_sim(port, args.sim_uvloop)
    runner: Callable[..., object] = asyncio.run
    if args.uvloop:
        import uvloop

        runner = uvloop.run
    try:
        if args.against:
            compare(port, args, runner)
            return
        rows: dict[str, list[Result]] = {}
        for _ in range(args.rounds):
            for r in (raw_blocking(port, args.seconds), driver_blocking(port, args.seconds),
                      runner(raw_async(port, args.seconds)), runner(driver_async(port, args.seconds)),
                      driver_blocking(port, args.seconds, streams=True),
                      runner(driver_async(port, args.seconds, streams=True))):
                rows.setdefault(r.name, []).append(r)  # type: ignore[union-attr]
        print(f"# driver round trips, 41h Get Gripper State, loopback, wsg sim (pid {proc.pid}), "
              f"{os.cpu_count()} CPUs, {args.rounds} interleaved rounds x {args.seconds:g} s"
              f"{', client on uvloop' if args.uvloop else ''}, sim on {'uvloop' if args.sim_uvloop else 'asyncio'}, "
              f"load average {os.getloadavg()[0]:.2f}")
        for label, pick in (("best", best), ("median", median)):
            res = {k: pick(v) for k, v in rows.items()}
            print(f"## {label} round of each client")
            for r in res.values():
                print(r.line())
            rb, db = res["raw blocking socket"], res["Gripper.gripper_state()"]
            ra, da = res["raw asyncio BufferedProtocol"], res["AsyncGripper.gripper_state()"]
            print(f"blocking: raw/driver rate ratio {rb.rate / db.rate:.2f}x, p50 ratio {db.p50 / rb.p50:.2f}x "
                  f"(target <= 1.3x)")
            print(f"asyncio:  raw/driver rate ratio {ra.rate / da.rate:.2f}x, p50 ratio {da.p50 / ra.p50:.2f}x "
                  f"(target <= 1.3x)")
            sb = res["Gripper.gripper_state() + 4 streams @10 ms"]
            sa = res["AsyncGripper.gripper_state() + 4 streams @10 ms"]
            print(f"added latency with 4 streams @10 ms: blocking p50 {sb.p50 - db.p50:+.1f} µs, "
                  f"p99 {sb.p99 - db.p99:+.1f} µs; asyncio p50 {sa.p50 - da.p50:+.1f} µs, "
                  f"p99 {sa.p99 - da.p99:+.1f} µs")
        print("## median of the per-round ratios")
        for kind, raw_name, drv_name in (("blocking", "raw blocking socket", "Gripper.gripper_state()"),
                                         ("asyncio ", "raw asyncio BufferedProtocol", "AsyncGripper.gripper_state()")):
            rate = statistics.median(r.rate / d.rate for r, d in zip(rows[raw_name], rows[drv_name], strict=True))
            p50 = statistics.median(d.p50 / r.p50 for r, d in zip(rows[raw_name], rows[drv_name], strict=True))
            print(f"{kind}: raw/driver rate ratio {rate:.2f}x, p50 ratio {p50:.2f}x (target <= 1.3x)")
    finally:
        proc.terminate()
        proc.wait(5)


if __name__ == "__main__":
    main()
