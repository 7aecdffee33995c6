"""The manual's gripping cycle (home, pre-position, grip, hold, release, back to start) over the
byte stream, in five variants. Each checks the frames on the wire, the 41h state and the 40h flags."""

from __future__ import annotations

import struct

from pywsg.protocol import CATALOG, Frame, FrameParser, GripperState, Status, SystemFlag, encode_frame

from .devrig import Rig, make_rig

S = Status
G = GripperState
SF = SystemFlag


class Wire:
    """A client on the byte stream: sends encoded frames, parses the device's bytes back."""

    def __init__(self, rig: Rig) -> None:
        self.rig = rig
        self.parser = FrameParser()
        rig.s.deliver = self._deliver
        self.received: list[Frame] = []

    def _deliver(self, f: Frame) -> None:
        self._take(f.encode())

    def _take(self, data: bytes) -> None:
        for ev in self.parser.feed(data):
            assert isinstance(ev, Frame), ev  # every byte the device sends is a valid frame
            self.received.append(ev)

    def send(self, cid: int, **values: object) -> list[tuple[int, Status | int]]:
        start = len(self.received)
        wire = encode_frame(cid, CATALOG[cid].encode_request(**values))  # type: ignore[arg-type]
        for f in self.rig.g.feed(self.rig.s, wire):
            self._take(f.encode())
        return [(f.command_id, f.status) for f in self.received[start:]]

    def wait(self, seconds: float) -> list[tuple[int, Status | int]]:
        start = len(self.received)
        self.rig.run(seconds)
        return [(f.command_id, f.status) for f in self.received[start:]]

    def state(self) -> GripperState:
        self.send(0x41, flags=0, period_ms=0)
        return GripperState(self.received[-1].params[0])

    def flags(self) -> SystemFlag:
        self.send(0x40, flags=0, period_ms=0)
        return SystemFlag(struct.unpack("<I", self.received[-1].params)[0])


def start_cycle(w: Wire) -> None:
    assert w.send(0x20, direction=1) == [(0x20, S.E_CMD_PENDING)]
    assert w.state() == G.POSITIONING and w.flags() & SF.SF_MOVING
    assert w.wait(5) == [(0x20, S.E_SUCCESS)]
    assert w.state() == G.IDLE and w.flags() & SF.SF_REFERENCED
    assert w.send(0x21, flags=0, width=70.0, speed=100.0) == [(0x21, S.E_CMD_PENDING)]
    assert w.state() == G.POSITIONING
    assert w.wait(5) == [(0x21, S.E_SUCCESS)]
    f = w.flags()
    assert f & SF.SF_TARGET_POS_REACHED and not f & SF.SF_MOVING
    assert w.state() == G.IDLE


def test_cycle_with_part() -> None:
    r = make_rig()
    w = Wire(r)
    start_cycle(w)
    r.g.faults.place_part(40.0)
    assert w.send(0x25, width=40.0, speed=50.0) == [(0x25, S.E_CMD_PENDING)]
    assert w.state() == G.GRIPPING
    assert w.wait(5) == [(0x25, S.E_SUCCESS)]
    assert w.state() == G.HOLDING
    f = w.flags()
    assert not f & (SF.SF_MOVING | SF.SF_CMD_FAILURE)
    r.run(10)  # hold
    assert w.state() == G.HOLDING
    assert w.send(0x26, width=70.0, speed=50.0) == [(0x26, S.E_CMD_PENDING)]
    assert w.state() == G.RELEASING
    assert w.wait(5) == [(0x26, S.E_SUCCESS)]
    assert w.state() == G.IDLE
    assert abs(r.g.width() - 70.0) < 1e-6  # back to start
    assert r.g.snapshot().statistics == (1, 0, 0)


def test_cycle_without_part() -> None:
    r = make_rig()
    w = Wire(r)
    start_cycle(w)
    assert w.send(0x25, width=40.0, speed=50.0) == [(0x25, S.E_CMD_PENDING)]
    assert w.wait(5) == [(0x25, S.E_CMD_FAILED)]
    assert w.state() == G.NO_PART
    assert w.flags() & SF.SF_CMD_FAILURE
    assert w.send(0x26, width=70.0, speed=50.0) == [(0x26, S.E_CMD_PENDING)]
    assert w.wait(5) == [(0x26, S.E_SUCCESS)]
    assert w.state() == G.IDLE
    assert not w.flags() & SF.SF_CMD_FAILURE
    assert r.g.snapshot().statistics == (1, 1, 0)


def test_cycle_part_removed_while_holding() -> None:
    r = make_rig()
    w = Wire(r)
    start_cycle(w)
    r.g.faults.place_part(40.0)
    w.send(0x25, width=40.0, speed=50.0)
    assert w.wait(5) == [(0x25, S.E_SUCCESS)]
    r.g.faults.remove_part()
    assert w.state() == G.PART_LOST
    assert not w.flags() & SF.SF_MOVING  # the drive stops where the part was (docs/fidelity.md)
    assert w.wait(5) == []
    assert abs(r.g.width() - 40.0) < 1e-6
    assert w.state() == G.PART_LOST  # persists until the next grip/release/pre-position
    assert w.send(0x26, width=70.0, speed=50.0) == [(0x26, S.E_CMD_PENDING)]
    assert w.wait(5) == [(0x26, S.E_SUCCESS)]
    assert w.state() == G.IDLE
    assert r.g.snapshot().statistics == (1, 0, 1)


def test_cycle_with_fast_stop_and_acknowledge() -> None:
    r = make_rig()
    w = Wire(r)
    start_cycle(w)
    r.g.faults.place_part(40.0)
    w.send(0x25, width=40.0, speed=20.0)
    r.run(0.5)
    assert w.send(0x23) == [(0x25, S.E_CMD_ABORTED), (0x23, S.E_SUCCESS)]
    assert w.state() == G.ERROR
    f = w.flags()
    assert f & SF.SF_FAST_STOP and not f & SF.SF_MOVING
    assert w.send(0x25, width=40.0, speed=20.0) == [(0x25, S.E_ACCESS_DENIED)]
    assert w.send(0x24, key="ack") == [(0x24, S.E_SUCCESS)]
    assert not w.flags() & SF.SF_FAST_STOP
    assert w.state() == G.ERROR  # until the next grip/release/pre-position
    assert w.send(0x25, width=40.0, speed=50.0) == [(0x25, S.E_CMD_PENDING)]
    assert w.wait(5) == [(0x25, S.E_SUCCESS)]
    assert w.state() == G.HOLDING
    w.send(0x26, width=70.0, speed=50.0)
    assert w.wait(5) == [(0x26, S.E_SUCCESS)]
    assert w.state() == G.IDLE


def test_cycle_with_soft_limits_in_the_way() -> None:
    r = make_rig()
    w = Wire(r)
    start_cycle(w)
    assert w.send(0x34, minus=38.0, plus=100.0) == [(0x34, S.E_SUCCESS)]
    # nominal width inside the restricted area: refused at once
    assert w.send(0x25, width=30.0, speed=50.0) == [(0x25, S.E_RANGE_ERROR)]
    assert w.flags() & SF.SF_CMD_FAILURE
    # no part: the clamping travel runs into the soft limit -> FAST STOP, grip aborted
    assert w.send(0x25, width=40.0, speed=50.0) == [(0x25, S.E_CMD_PENDING)]
    assert w.wait(5) == [(0x25, S.E_CMD_ABORTED)]
    f = w.flags()
    assert f & SF.SF_FAST_STOP and f & SF.SF_SOFT_LIMIT_MINUS
    assert w.state() == G.ERROR
    assert abs(r.g.width() - 38.0) < 1e-3  # stopped at the limit, never inside
    assert w.send(0x24, key="ack") == [(0x24, S.E_SUCCESS)]
    # only motion out of the restricted area is possible; into it is a range error
    assert w.send(0x21, flags=0, width=20.0, speed=50.0) == [(0x21, S.E_RANGE_ERROR)]
    assert w.send(0x26, width=70.0, speed=50.0) == [(0x26, S.E_CMD_PENDING)]
    assert w.wait(5) == [(0x26, S.E_SUCCESS)]
    assert w.state() == G.IDLE
    assert not w.flags() & (SF.SF_SOFT_LIMIT_MINUS | SF.SF_FAST_STOP)
    assert any("soft limit" in m for m in r.g.log.messages())
