"""Fuzz the virtual gripper's byte entry points: a TCP stream (``feed``) and UDP datagrams (``handle_datagram``).

    .venv/bin/python fuzz/fuzz_device.py -max_total_time=60            # atheris
    .venv/bin/python fuzz/fuzz_device.py --hypothesis --examples 2000  # without atheris

Input: byte 0 sets the chunk size (1..64) the rest is cut into. Each chunk is fed to a TCP session and
sent as one datagram to a UDP session, and the device's clock advances 7 ms (its ``poll`` runs) between
chunks, so requests, motions and auto-updates interleave. A finding is:

- any exception out of the device;
- a reply that is not a well-formed frame (encodes and re-parses to itself, carries a status code);
- a parser holding more than one maximal frame plus one chunk;
- more reply bytes to a datagram than 2.5x its size plus one reply (amplification);
- a device that afterwards does not answer a fresh client's Loop (06h) correctly, or reports a
  width outside 0..stroke.
"""

from __future__ import annotations

import math
import struct
import sys
from pathlib import Path
from typing import Any

from hypothesis import strategies as st

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _harness import instrumented, main

with instrumented(__name__):
    from pywsg.device import ManualClock, VirtualGripper
    from pywsg.protocol import CATALOG, MAX_PAYLOAD, Frame, Status, encode_frame
    from pywsg.protocol.parser import whole_frame

_LOOSE = 2**16  # whole_frame's SIZE cap when re-parsing a reply (replies may exceed request caps)


def _check_reply(frame: Frame) -> None:
    raw = frame.encode()
    again = whole_frame(raw, True, lambda _cid: _LOOSE)
    if again != frame:
        raise AssertionError(f"reply does not re-parse to itself: {raw.hex(' ')}")
    if len(frame.payload) < 2:
        raise AssertionError(f"reply without a status code: {raw.hex(' ')}")


def test_one_input(data: bytes) -> None:
    if not data:
        return
    chunk = data[0] % 64 + 1
    body = data[1:]
    clock = ManualClock()
    gripper = VirtualGripper("wsg50", clock=clock)
    deferred: list[Frame] = []
    tcp = gripper.open_session("tcp", peer="fuzz-tcp", deliver=deferred.append)
    udp = gripper.open_session("udp", peer="fuzz-udp", deliver=deferred.append)
    for i in range(0, len(body), chunk):
        piece = body[i : i + chunk]
        for f in gripper.feed(tcp, piece):
            _check_reply(f)
        if tcp.parser.buffered > MAX_PAYLOAD + 8 + chunk:
            raise AssertionError(f"parser holds {tcp.parser.buffered} bytes")
        replies = gripper.handle_datagram(udp, piece)
        for f in replies:
            _check_reply(f)
        out = sum(len(f.payload) + 8 for f in replies)
        if out > 2.5 * len(piece) + 10 + MAX_PAYLOAD + 2:
            raise AssertionError(f"{len(piece)}-byte datagram answered with {out} bytes")
        clock.advance(0.007)
        gripper.poll()
        for f in deferred:
            _check_reply(f)
        deferred.clear()
    _check_alive(gripper, clock, tcp)


def _check_alive(gripper: Any, clock: ManualClock, tcp: Any) -> None:
    """The device still works for a well-behaved client after the input."""
    gripper.close_session(tcp)
    clock.advance(1.0)
    gripper.poll()
    fresh = gripper.open_session("tcp", peer="after")
    replies = gripper.feed(fresh, encode_frame(0x06, b"alive?"))
    loop = [f for f in replies if f.command_id == 0x06]
    if len(loop) != 1 or loop[0].status != Status.E_SUCCESS or loop[0].params != b"alive?":
        raise AssertionError(f"Loop after the input answered {[f.hex() for f in replies]}")
    width = [f for f in gripper.feed(fresh, encode_frame(0x43, CATALOG[0x43].encode_request(flags=0, period_ms=0)))
             if f.command_id == 0x43]
    if len(width) != 1 or width[0].status != Status.E_SUCCESS:
        raise AssertionError(f"width read after the input answered {[f.hex() for f in width]}")
    (mm,) = struct.unpack("<f", width[0].params[:4])
    if not math.isfinite(mm) or not -0.001 <= mm <= gripper.profile.stroke + 0.001:
        raise AssertionError(f"width {mm} mm outside the stroke")


def _request(cid: int, payload: bytes) -> bytes:
    return encode_frame(cid, payload)


# shaped input: valid requests for catalog commands with fuzzed parameters, forged headers, garbage
_valid = st.builds(_request, st.sampled_from(sorted(CATALOG)), st.binary(max_size=24))
_forged = st.builds(lambda cid, size: b"\xaa\xaa\xaa" + bytes([cid]) + size.to_bytes(2, "little"),
                    st.integers(0, 255), st.integers(0, 0xFFFF))
inputs = st.builds(lambda chunk, parts: bytes([chunk]) + b"".join(parts), st.integers(0, 255),
                   st.lists(st.one_of(_valid, _valid, _forged, st.binary(max_size=30)), max_size=16))


if __name__ == "__main__":
    main(test_one_input, inputs)
