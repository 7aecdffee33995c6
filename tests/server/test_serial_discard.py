"""Serial output discard drops whole frames only (a stalled pty reader never sees a torn frame)."""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from typing import Any

import serial

from pywsg.protocol import Frame, FrameParser, Status
from pywsg.server import Limits

from .conftest import SimThread


def test_stalled_pty_reader_sees_only_whole_frames(sim_factory: Callable[..., SimThread]) -> None:
    """000 §1.2.1 framing: what is discarded is whole frames; every byte read parses cleanly."""
    st = sim_factory(tcp_port=None, udp_port=None, serial="pty", limits=Limits(output_soft=1024, output_hard=3000))
    port = serial.Serial(st.g.serial_path, 115200, timeout=0.05)
    payloads = [bytes((i + k) % 0xA0 for k in range(1 + (i * 37) % 256)) for i in range(400)]  # no AAh
    for p in payloads:  # the reader is stalled: nothing is read while ~120 KB of replies pile up
        port.write(Frame(0x06, p).encode())
    time.sleep(0.5)
    srv: Any = st.sim.grippers[0].serial
    assert st.call(lambda: srv.dropped) > 0, "nothing was discarded: the test did not stall the reader"
    parser = FrameParser()
    events = []
    deadline = time.monotonic() + 5
    idle = 0
    while time.monotonic() < deadline and idle < 5:
        data = port.read(65536)
        idle = 0 if data else idle + 1
        events += parser.feed(data)
    port.close()
    frames = [e for e in events if isinstance(e, Frame)]
    errors = [e for e in events if not isinstance(e, Frame)]
    assert not errors, errors[:3]
    assert frames and parser.buffered == 0
    sent = set(payloads)
    for f in frames:
        assert f.command_id == 0x06 and f.status == Status.E_SUCCESS and f.params in sent
    assert len(frames) < len(payloads)
    assert os.path.exists(st.g.serial_path)
