"""Serial output discard (issue 13 item 7): a stalled pty reader loses whole frames, never part of one."""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import serial

from pywsg.protocol import Frame, FrameParser, ParseError, Status
from pywsg.server import Limits

from .conftest import SimThread


def test_stalled_pty_reader_loses_whole_frames_only(sim_factory: Callable[..., SimThread]) -> None:
    st = sim_factory(tcp_port=None, udp_port=None, serial="pty", limits=Limits(output_soft=2048, output_hard=8192))
    port = serial.Serial(st.g.serial_path, 115200, timeout=0.2)
    payloads = [i.to_bytes(2, "little") + bytes(251) for i in range(1000)]  # 263-byte replies, odd sizes
    for i in range(0, len(payloads), 25):  # ~260 KB of replies while nobody reads: pty full, then our queue
        port.write(b"".join(Frame(0x06, p).encode() for p in payloads[i : i + 25]))
    time.sleep(0.5)
    srv: Any = st.sim.grippers[0].serial
    assert st.call(lambda: srv.dropped) > 0
    # the reader wakes up: every byte it gets parses as whole, valid replies, in order
    parser = FrameParser()
    events: list[Any] = []
    while data := port.read(1 << 16):
        events += parser.feed(data)
    assert not [e for e in events if isinstance(e, ParseError)], [e for e in events if isinstance(e, ParseError)][:3]
    frames = [e for e in events if isinstance(e, Frame)]
    assert 0 < len(frames) < len(payloads)
    seen = [int.from_bytes(f.params[:2], "little") for f in frames]
    assert all(f.command_id == 0x06 and f.status == Status.E_SUCCESS for f in frames)
    assert seen == sorted(seen) and seen[-1] == len(payloads) - 1  # the newest survive, order kept
    assert parser.buffered == 0
    port.close()
