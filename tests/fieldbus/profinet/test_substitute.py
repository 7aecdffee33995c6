"""Substitute values: what the device does with outputs its controller marks not valid (issue 31 item 1).

IEC 61158-6-10: a consumer whose provider is in STOP (DataStatus.ProviderState 0), sends DataValid 0 or
IOPS BAD does not use that data; the device uses substitute values instead — here a zero output image, so a
JOG level drops and no edge fires (002 §4.7: JOG+/JOG- are levels). Back in RUN with GOOD data, edges are
judged against the substitute image. The real device (a VirtualGripper on a manual clock) and the real
connection manager and frame codec, fed the frames a controller sends; the wire version is in
test_wire_substitute.py.
"""

from __future__ import annotations

import struct

import pytest

from pywsg.fieldbus.image import CmdFlag, OutputImage
from pywsg.fieldbus.profinet import rpc
from pywsg.fieldbus.profinet.device import ProfinetDevice
from pywsg.fieldbus.profinet.rt import DS_DEVICE, DS_RUN, IOXS_BAD, IOXS_GOOD
from pywsg.protocol import SystemFlag

from ..test_controller import Rig
from .test_sans_io import REAL_EXPECTED, _connect_args, _rpc_request

C = CmdFlag
STOP = DS_DEVICE & ~DS_RUN   # 25h: what a controller going to STOP sends


class Bench:
    """A ProfinetDevice on ``lo`` (no socket opened: frames go in by hand) with one IO AR connected."""

    def __init__(self) -> None:
        self.rig = Rig()
        self.dev = ProfinetDevice(self.rig.g, "lo", self.rig.ctl, station_name="wsg50")
        reply = self.dev.cm.handle(_rpc_request(rpc.OP_CONNECT, _connect_args(REAL_EXPECTED)), "192.0.2.1", 1)
        assert reply is not None and self.dev.cm.io_ar is not None and self.dev.codec is not None
        self.ar = self.dev.cm.io_ar
        assert self.ar.output_cr is not None
        self.offset = next(o.offset for o in self.ar.output_cr.data if (o.slot, o.subslot) == (1, 1))
        self.counter = 0

    def frame(self, image: OutputImage, status: int = DS_DEVICE, iops: int = IOXS_GOOD) -> None:
        assert self.ar.output_cr is not None
        c = bytearray(self.ar.output_cr.data_length)
        c[self.offset:self.offset + 8] = image.pack()
        c[self.offset + 8] = iops
        self.counter = (self.counter + 256) & 0xFFFF
        self.dev._output_frame(struct.pack("!H", self.ar.output_frame_id) + bytes(c)
                               + struct.pack("!HBB", self.counter, status, 0))

    def width(self) -> float:
        return self.rig.ctl.input_image().width / 100

    def moving(self) -> bool:
        return bool(self.rig.ctl.input_image().sysstate & SystemFlag.SF_MOVING)


@pytest.fixture
def bench() -> Bench:
    b = Bench()
    b.rig.home()
    b.rig.settle()
    return b


JOG_PLUS = OutputImage(C.JOG_PLUS, 0, 0, 2000, 0)   # JOG+ at 20 mm/s


@pytest.mark.parametrize("how", ["provider STOP", "IOPS BAD"])
def test_jog_stops_when_the_controller_stops_or_sends_iops_bad(bench: Bench, how: str) -> None:
    """With JOG+ held in the image, a frame with ProviderState STOP (DataStatus 25h) or IOPS BAD stops the
    jog at once and the fingers stay put (the defect: 10 mm more per second)."""
    bench.rig.write(C.JOG_MINUS, speed=50)   # homing ends open: close a little first, so JOG+ has room
    bench.rig.run(0.5)
    bench.rig.write(C.NONE)
    bench.frame(JOG_PLUS)
    bench.rig.run(0.3)
    assert bench.moving()
    start = bench.width()
    if how == "provider STOP":
        bench.frame(JOG_PLUS, status=STOP)
    else:
        bench.frame(JOG_PLUS, iops=IOXS_BAD)
    assert bench.dev.consumer.substituting
    assert "substitute values" in bench.dev.bus_state()["Outputs"]
    bench.rig.run(0.2)   # the jog's deceleration
    stopped = bench.width()
    for _ in range(10):   # one second of such frames: nothing moves
        if how == "provider STOP":
            bench.frame(JOG_PLUS, status=STOP)
        else:
            bench.frame(JOG_PLUS, iops=IOXS_BAD)
        bench.rig.run(0.1)
    assert not bench.moving()
    assert abs(bench.width() - stopped) < 0.01 and stopped - start < 2.0, (start, stopped, bench.width())
    assert bench.rig.ctl.output_image == OutputImage()   # the substitute image is what the controller applies
    # back to RUN with GOOD data and JOG+ still raised: the level applies again (judged against zeros)
    bench.frame(JOG_PLUS)
    bench.rig.run(0.2)
    assert bench.moving() and not bench.dev.consumer.substituting


def test_edges_are_judged_against_the_substitute_image(bench: Bench) -> None:
    """A MOVE bit raised before STOP and still raised on return to RUN is a new edge: the command fires
    again (against the substitute image), and during STOP no edge fires at all."""
    move = OutputImage(C.MOVE, 0, 4000, 5000, 0)   # MOVE to 40 mm at 50 mm/s
    bench.frame(move)
    bench.rig.settle()
    moves = sum("MOVE width" in e.text for e in bench.rig.ctl.events)
    assert moves == 1 and abs(bench.width() - 40) < 0.1
    bench.rig.write(C.NONE, width=60, speed=50)   # another interface moves the fingers away meanwhile
    bench.rig.pulse(C.MOVE)
    bench.rig.settle()
    bench.frame(move)   # still the image PROFINET applied: no edge
    bench.frame(move, status=STOP)
    bench.frame(OutputImage(C.MOVE | C.HOMING, 0, 4000, 5000, 0), status=STOP)   # ignored: not valid
    bench.rig.settle()
    assert sum("MOVE width" in e.text for e in bench.rig.ctl.events) == moves + 1
    assert "HOMING" not in " ".join(e.text for e in bench.rig.ctl.events[-3:])
    bench.frame(move)   # RUN again, MOVE still raised: a rising edge against the substitute zeros
    bench.rig.settle()
    assert sum("MOVE width" in e.text for e in bench.rig.ctl.events) == moves + 2
    assert abs(bench.width() - 40) < 0.1


def test_a_release_also_drops_the_outputs_without_fast_stop(bench: Bench) -> None:
    """A Release ends the AR without FAST STOP (it is no lost master), but a JOG level does not outlive it."""
    bench.frame(OutputImage(C.JOG_MINUS, 0, 0, 2000, 0))
    bench.rig.run(0.2)
    assert bench.moving()
    bench.dev.cm.drop(bench.ar, "released by the controller")
    bench.rig.run(0.3)
    img = bench.rig.ctl.input_image()
    assert not img.sysstate & SystemFlag.SF_MOVING and not img.sysstate & SystemFlag.SF_FAST_STOP
