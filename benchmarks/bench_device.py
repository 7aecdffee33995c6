"""Virtual gripper benchmark: firmware cost per command (µs) and full grip cycles per second.

Run: .venv/bin/python benchmarks/bench_device.py [--quick]
Everything runs on a ManualClock, so the figures are pure CPU cost of the sans-IO firmware.
"""

from __future__ import annotations

import argparse
import platform
import struct
import time

from pywsg.device import ManualClock, VirtualGripper
from pywsg.protocol import CATALOG, Frame, encode_frame


def per_call_us(fn: object, n: int) -> float:
    assert callable(fn)
    best = float("inf")
    for _ in range(5):
        t0 = time.perf_counter()
        for _ in range(n):
            fn()
        best = min(best, (time.perf_counter() - t0) / n)
    return best * 1e6


def bench_commands(n: int) -> None:
    clock = ManualClock()
    g = VirtualGripper("wsg50", clock=clock)
    s = g.open_session("tcp")
    g.handle_frame(s, Frame(0x20, b"\x01"))
    clock.advance(5)
    g.poll()
    cases = {
        "41h get gripper state": Frame(0x41, CATALOG[0x41].encode_request(flags=0, period_ms=0)),
        "40h get system state": Frame(0x40, CATALOG[0x40].encode_request(flags=0, period_ms=0)),
        "43h get opening width": Frame(0x43, CATALOG[0x43].encode_request(flags=0, period_ms=0)),
        "31h get acceleration": Frame(0x31),
        "06h loop (8 bytes)": Frame(0x06, b"12345678"),
        "90h unknown": Frame(0x90),
    }
    print(f"{'command':28} {'handle_frame':>13} {'feed+encode':>12}")
    for name, frame in cases.items():
        a = per_call_us(lambda frame=frame: g.handle_frame(s, frame), n)
        wire = frame.encode()

        def full(wire: bytes = wire) -> None:
            for reply in g.feed(s, wire):
                reply.encode()

        b = per_call_us(full, n)
        print(f"{name:28} {a:10.2f} µs {b:9.2f} µs")
    # a motion command with its final reply: pending + poll at the due time
    t = 0.0

    def move() -> None:
        nonlocal t
        g.handle_frame(s, Frame(0x21, b"\x00" + struct.pack("<ff", 20.0 if t % 2 else 90.0, 400.0)))
        due = g.next_due()
        assert due is not None
        clock.set(due)
        g.poll()
        t += 1

    print(f"{'21h pre-position + final':28} {per_call_us(move, n // 10):10.2f} µs  (pending, next_due, poll)")
    idle = per_call_us(g.poll, n)
    print(f"{'poll() with nothing due':28} {idle:10.2f} µs")


def bench_cycles(grippers: int, cycles: int) -> None:
    """Each gripper: pre-position 70, grip a 40 mm part, release to 70, via frames + poll."""
    clock = ManualClock()
    fleet = []
    for _ in range(grippers):
        g = VirtualGripper("wsg50", clock=clock)
        s = g.open_session("tcp")
        g.handle_frame(s, Frame(0x20, b"\x01"))
        g.faults.place_part(40.0)
        fleet.append((g, s))
    clock.advance(5)
    for g, _ in fleet:
        g.poll()
    steps = [
        encode_frame(0x21, b"\x00" + struct.pack("<ff", 70.0, 200.0)),
        encode_frame(0x25, struct.pack("<ff", 40.0, 100.0)),
        encode_frame(0x26, struct.pack("<ff", 70.0, 200.0)),
    ]
    t0 = time.perf_counter()
    finals = 0
    for _ in range(cycles):
        for wire in steps:
            for g, s in fleet:
                g.feed(s, wire)
            # the fleet shares one clock: jump to the latest due time, then collect
            due = max(d for g, _ in fleet if (d := g.next_due()) is not None)
            clock.set(due)
            for g, _ in fleet:
                finals += len(g.poll())
    dt = time.perf_counter() - t0
    assert finals == grippers * cycles * 3, finals
    print(f"{grippers} grippers x {cycles} grip cycles: {grippers * cycles / dt:,.0f} cycles/s "
          f"({dt / (grippers * cycles) * 1e6:.0f} µs per cycle of 3 motion commands)")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true")
    args = ap.parse_args()
    print(f"Python {platform.python_version()} on {platform.machine()}, {platform.processor() or '?'}")
    bench_commands(2000 if args.quick else 20000)
    bench_cycles(100 if args.quick else 1000, 5 if args.quick else 10)


if __name__ == "__main__":
    main()
