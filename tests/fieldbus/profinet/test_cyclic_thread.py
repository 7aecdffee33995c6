"""The cyclic path keeps its cycle while the rest of the process is busy (issue 31 item 16).

The device's input frames come from a thread with a raw socket of its own (pywsg.fieldbus.profinet.cyclic),
not from the event loop: while the loop's thread is stuck in Python (a web request, a TCP flood, a Modbus
master being served), the frames still leave. Here the CyclicThread runs in the device namespace of a veth
pair and the test's main thread then computes without a pause; the frames arriving in the controller
namespace during that stall are counted against those of an equally long quiet stretch measured just
before (no absolute time bound). Before the thread, the loop sent the frames: none left during a stall.
"""

from __future__ import annotations

import ctypes
import os
import socket
import threading
import time
from collections.abc import Callable
from typing import TypeVar

from pywsg.fieldbus.profinet.cyclic import CyclicThread
from pywsg.fieldbus.profinet.ether import ETH_P_PNIO, ether

from .conftest import Wire

T = TypeVar("T")
CYCLE_S = 0.004
FRAME_ID = 0xC123


def in_namespace(ns: str, fn: Callable[[], T]) -> T:
    """``fn()`` on a helper thread that entered network namespace ``ns`` (its sockets stay there)."""
    out: list[T | BaseException] = []

    def run() -> None:
        try:
            fd = os.open(f"/run/netns/{ns}", os.O_RDONLY)
            try:
                if ctypes.CDLL(None, use_errno=True).setns(fd, 0x40000000) != 0:
                    raise OSError(ctypes.get_errno(), "setns")
            finally:
                os.close(fd)
            out.append(fn())
        except BaseException as exc:
            out.append(exc)

    t = threading.Thread(target=run)
    t.start()
    t.join(10)
    if isinstance(out[0], BaseException):
        raise out[0]
    return out[0]


def _count(rx: socket.socket, seconds: float, busy: bool) -> int:
    """Input frames received within ``seconds``; ``busy``: the main thread computes meanwhile (a stalled
    event loop) and counts afterwards from the socket's queue."""
    end = time.monotonic() + seconds
    if busy:
        x = 0
        while time.monotonic() < end:
            x += sum(range(200))   # pure Python: the GIL's holder, no yield to an event loop
    else:
        time.sleep(seconds)
    n = 0
    while True:
        try:
            data = rx.recv(2048)
        except BlockingIOError:
            return n
        off = 16 if data[12:14] == b"\x81\x00" else 12
        n += int.from_bytes(data[off + 2:off + 4], "big") == FRAME_ID


def test_input_frames_leave_on_time_while_the_process_is_busy(wire: Wire) -> None:
    rx = wire.socket_in(wire.controller_ns, socket.AF_PACKET, socket.SOCK_RAW, socket.htons(ETH_P_PNIO))
    rx.bind((wire.iface, ETH_P_PNIO))
    rx.setblocking(False)
    frame = ether(rx.getsockname()[4], bytes(6), ETH_P_PNIO, FRAME_ID.to_bytes(2, "big") + bytes(44), tag=True)
    rt = in_namespace(wire.device_ns, lambda: CyclicThread(
        wire.iface, b"\x02" * 6, 0xC000, CYCLE_S, build=lambda inputs: frame, consume=lambda p: None,
        judge=lambda now: "", post=lambda fn, *a: None, apply=lambda image: None, expired=lambda why: None,
        sent=lambda: None))
    rt.start()
    try:
        time.sleep(0.2)
        _count(rx, 0.0, busy=False)   # drop what came before
        quiet = _count(rx, 1.0, busy=False)
        stalled = _count(rx, 1.0, busy=True)
    finally:
        rt.stop()
    assert quiet > 0, quiet   # the baseline: the cycle runs at all here (however loaded the machine)
    assert stalled >= 0.3 * quiet, (quiet, stalled)   # the loop-driven cycle sent none
