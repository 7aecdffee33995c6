"""Issue 23 item 15: what a flood costs the sim per byte. A frame with a bad CRC (000 §2.3: answered
E_CHECKSUM_ERROR) must cost no more than an ordinary request (06h Loop, 000 §3.1.1) of the same
size: before, each bad frame advanced the device, marked it changed and built its reply afresh
(1 MiB: 0.6 s against 0.42 s for valid requests). Ratios within the test, never seconds."""

from __future__ import annotations

import os
import time

from pywsg.device import ManualClock, VirtualGripper
from pywsg.protocol import Frame, Status

SLICE = 4096  # what the TCP server parses per loop turn (server.tcp.READ_SLICE)


def _cost(blob: bytes) -> tuple[float, int]:
    """CPU seconds for one fresh gripper to read ``blob`` (and encode its replies), and the replies."""
    g = VirtualGripper("wsg50", clock=ManualClock())
    s = g.open_session("tcp", peer="flood", deliver=lambda f: None)
    n = 0
    t0 = time.process_time()
    for i in range(0, len(blob), SLICE):
        replies = g.feed(s, blob[i:i + SLICE])
        n += len(b"".join([r.encode() for r in replies])) // 10
    return time.process_time() - t0, n


def test_bad_crc_frames_cost_no_more_than_valid_requests() -> None:
    count = 256 * 1024 // 10
    valid = Frame(0x06, b"xy").encode() * count           # 10-byte Loop requests
    bad = (Frame(0x06, b"xy").encode()[:-2] + b"\0\0") * count  # the same frames, CRC zeroed
    noise = os.urandom(len(valid))
    _cost(valid)  # warm-up
    base = min(_cost(valid)[0] for _ in range(3))
    cost, answers = min(_cost(bad) for _ in range(3))
    assert answers == count  # every bad frame answered, as the manual asks
    assert cost < 1.1 * base, (cost, base)
    assert _cost(noise)[0] < base  # garbage (no frames) is cheaper still
    g = VirtualGripper("wsg50", clock=ManualClock())
    s = g.open_session("tcp", peer="x", deliver=lambda f: None)
    (reply,) = g.feed(s, bad[:10])
    assert reply.status == Status.E_CHECKSUM_ERROR and reply.command_id == 0x06
