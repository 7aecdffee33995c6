"""Issue 23 item 15: what a flood costs `wsg proxy` per byte. Frames the log does not show (over
``--log-rate``) are counted in bulk, not parsed one by one, so 8-byte frames with bad CRCs (131,072
a MiB, and as many replies) cost about what honest traffic of the same size costs.

The proxy runs in-process on a loop of its own; its CPU is that loop thread's CPU time, from start
to close (close waits until everything read is decoded). The gripper is a real `SimThread`. The
bound is a ratio to honest traffic sent the same way in the same test, never seconds."""

from __future__ import annotations

import io
import os
import time
from collections.abc import Iterator

import pytest

from pywsg.capture.commlog import CommLog
from pywsg.protocol import Command, Frame
from pywsg.testing import SimThread
from pywsg.testing.host import LoopThread
from pywsg.testing.proxy import Proxy

from .conftest import send_then_marker

SIZE = 256 * 1024


@pytest.fixture
def loop() -> Iterator[LoopThread]:
    lt = LoopThread("proxy")
    yield lt
    lt.close()


def _proxy_cpu(loop: LoopThread, sim: SimThread, blob: bytes) -> tuple[float, Proxy, str]:
    """Loop-thread CPU seconds of a fresh proxy (text log and JSON lines) carrying ``blob`` and the
    sim's answers, until it has closed; the proxy and its text log."""
    text, jsonl = io.StringIO(), io.StringIO()
    cpu0 = loop.call(time.thread_time)
    proxy = loop.run(Proxy(sim.url, log=CommLog(text=text, jsonl=jsonl), log_rate=100).start())
    try:
        send_then_marker(proxy.port_bound, blob)
    finally:
        loop.run(proxy.close(), timeout=30)
    return loop.call(time.thread_time) - cpu0, proxy, text.getvalue()


def test_a_bad_crc_flood_costs_the_proxy_about_what_honest_traffic_costs(loop: LoopThread) -> None:
    """Before: 8-byte bad-CRC frames cost the proxy ~0.75 s/MiB (the sim answering them 0.39), 3-7x the
    same bytes of valid 256-byte Loop requests (different payloads, so each is checked). Now 0.4-0.9x
    (bound 2.5x); every frame is still counted, and the log says how many it did not show."""
    bad = (Frame(0x50).encode()[:-2] + b"\0\0") * (SIZE // 8)
    loops = b"".join(Frame(Command.LOOP, os.urandom(250)).encode() for _ in range(SIZE // 258))
    with SimThread() as sim:
        _proxy_cpu(loop, sim, loops[: 16 * 1024])  # warm-up: imports, first connection
        honest, _, _ = _proxy_cpu(loop, sim, loops)
        flood, proxy, text = _proxy_cpu(loop, sim, bad)
    assert flood < 2.5 * honest, (flood, honest)
    assert proxy.stats.frames["rx"] == SIZE // 8 + 1  # one E_CHECKSUM_ERROR answer each, and the marker's
    assert proxy.stats.frames["tx"] == 1
    assert "not logged (over 100/s): wrong checksum x" in text
