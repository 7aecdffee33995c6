"""Hostile input over CAN (python-can ``virtual`` bus): what 1 MiB of 8-byte CAN frames costs the sim.

A virtual bus does not cross processes (and this machine has no ``vcan``), so the sim runs in a
thread of this process (:class:`pywsg.testing.SimThread`, stock asyncio) and the flooding client in
two other threads (one sends, one reads the answers). Printed per attack:

- the sim's loop-thread CPU (s per MiB sent, ``time.thread_time`` on that thread),
- the CPU of the thread that reads the bus for the sim (python-can's ``Notifier``, or since issue 33
  item 13 the sim's own batch reader), and the sim's total (loop + reader),
- the baseline: the CPU python-can takes to send the flood (the client's ``bus.send`` of the same CAN
  frames, in the sending thread of the same run),
- the sim's CPU (loop + reader) per second of a saturated classic CAN bus at 1 Mbit/s
  (~8,000 8-byte frames a second, so 1 MiB is ~16 s of bus time),
- the waits of a well-behaved UDP client of the same sim, in a process of its own, sending Loop
  requests back to back during a second run (the client's threads share the sim's GIL: an in-process
  artefact a sim on a real bus would not have),
- answers the client received (frames).

    .venv/bin/python benchmarks/abuse_can.py [--mib 1]

``bench_abuse.py`` runs it (with ``--sim-path`` as ``PYTHONPATH``, so the sim is the one measured).
"""

from __future__ import annotations

import argparse
import multiprocessing
import os
import threading
import time
import uuid
from multiprocessing.connection import Connection

import can
import psutil
from bench_abuse import MIB, Waiter

from pywsg.protocol import Frame, FrameParser, Status
from pywsg.testing import SimThread

BUS_FRAMES_PER_S = 8000  # classic CAN at 1 Mbit/s, 8-byte data frames (~111-135 bits each)


def _waiter(port: int, conn: Connection) -> None:
    """In a child process: UDP Loop requests until told to stop; sends back (p50, p99, max) in s."""
    w = Waiter(port)
    w.start()
    conn.recv()
    conn.send(w.finish())


def _thread_cpu(native_id: int) -> float:
    for t in psutil.Process().threads():
        if t.id == native_id:
            return float(t.user_time + t.system_time)
    return 0.0


def _flood(st: SimThread, channel: str, units: list[bytes]) -> tuple[float, float, float, int, int]:
    """Send ``units`` (one CAN frame each) then a marker request; (loop CPU s, reader CPU s,
    client send CPU s, reply CAN frames received, answers)."""
    marker = Frame(0x06, b"marker!").encode()
    want = Frame.reply(0x06, Status.E_SUCCESS, b"marker!").encode()
    msgs = [can.Message(arbitration_id=0x01, data=u, is_extended_id=False) for u in units]
    msgs += [can.Message(arbitration_id=0x01, data=marker[i : i + 8], is_extended_id=False)
             for i in range(0, len(marker), 8)]
    notifier = next(t for t in threading.enumerate() if t.name.startswith(("Notifier", "can-reader")))
    bus = can.Bus(interface="virtual", channel=channel)
    got = bytearray()
    frames = 0

    def read() -> None:
        nonlocal frames
        while (msg := bus.recv(30)) is not None:
            frames += 1
            got.extend(msg.data)
            if got.endswith(want):
                return

    reader = threading.Thread(target=read, daemon=True)
    time.sleep(0.2)
    loop0, n0 = st.call(time.thread_time), _thread_cpu(notifier.native_id or 0)
    reader.start()
    send0 = time.thread_time()
    for m in msgs:
        bus.send(m)
    send = time.thread_time() - send0
    reader.join(300)
    loop1, n1 = st.call(time.thread_time), _thread_cpu(notifier.native_id or 0)
    bus.shutdown()
    answers = sum(1 for e in FrameParser().feed(bytes(got)) if isinstance(e, Frame))
    return loop1 - loop0, n1 - n0, send, frames, answers


def case(name: str, units: list[bytes]) -> None:
    mib = len(units) * 8 / MIB
    channel = f"abuse-{uuid.uuid4().hex[:8]}"
    with SimThread(tcp_port=None, udp_port=None, can_channel=channel) as st:
        loop_cpu, notifier_cpu, send, frames, answers = _flood(st, channel, units)
    channel = f"abuse-{uuid.uuid4().hex[:8]}"
    with SimThread(tcp_port=None, udp_port=0, can_channel=channel) as st:
        ctx = multiprocessing.get_context("spawn")
        mine, theirs = ctx.Pipe()
        child = ctx.Process(target=_waiter, args=(st.g.udp_port, theirs))
        child.start()
        time.sleep(1.0)  # the child's start-up
        _flood(st, channel, units)
        mine.send("stop")
        p50, p99, worst = mine.recv()
        child.join(10)
    per_bus_s = (loop_cpu + notifier_cpu) / (len(units) / BUS_FRAMES_PER_S)
    print(f"{name:44s} {loop_cpu / mib:8.3f} {notifier_cpu / mib:8.3f} {(loop_cpu + notifier_cpu) / mib:8.3f} "
          f"{send / mib:8.3f} {per_bus_s:8.3f} {p50 * 1e3:7.2f} {p99 * 1e3:7.2f} {worst * 1e3:7.1f} "
          f"{frames:7d} {answers:9d}", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--mib", type=float, default=1.0, help="bytes per attack, in MiB")
    args = ap.parse_args()
    n = int(args.mib * MIB) // 8
    bad = Frame(0x06).encode()[:-2] + b"\0\0"  # 8 bytes: a whole frame in one CAN frame
    cases = [
        ("CAN (virtual bus): random 8-byte frames", [os.urandom(8) for _ in range(n)]),
        ("CAN: 8-byte frames with bad CRCs", [bad] * n),
        ("CAN: valid Loop requests (06h, 8 B)", [Frame(0x06).encode()] * n),
    ]
    print(f"{'CAN, in-process, s/MiB':44s} {'loop':>8s} {'reader':>8s} {'sim':>8s} {'client send':>8s} "
          f"{'CPU s/bus s':>8s} {'p50 ms':>7s} {'p99 ms':>7s} {'max ms':>7s} {'CAN frames':>7s} {'answers':>9s}",
          flush=True)
    for name, units in cases:
        case(name, units)


if __name__ == "__main__":
    main()
