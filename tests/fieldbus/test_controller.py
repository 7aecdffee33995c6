"""Fieldbus controller on the real virtual gripper, injected clock (002 §3.1, §4; docs/fidelity.md)."""

from __future__ import annotations

from collections.abc import Callable

import pytest

from pywsg.device import ManualClock, VirtualGripper
from pywsg.fieldbus.controller import FieldbusController
from pywsg.fieldbus.image import CmdFlag, InputImage, OutputImage
from pywsg.protocol import GripperState, Status, SystemFlag

C = CmdFlag
SF = SystemFlag
GS = GripperState


class Rig:
    def __init__(self, model: str = "wsg50") -> None:
        self.clock = ManualClock()
        self.g = VirtualGripper(model, clock=self.clock)
        self.ctl = FieldbusController(self.g)

    def run(self, dt: float) -> None:
        end = self.clock.now + dt
        while (nd := self.g.next_due()) is not None and nd <= end:
            self.clock.set(max(nd, self.clock.now))
            self.g.poll()
        self.clock.set(end)
        self.g.poll()

    def until(self, pred: Callable[[InputImage], bool], limit: float = 10.0, step: float = 0.005) -> InputImage:
        t = 0.0
        while t < limit:
            img = self.ctl.input_image()
            if pred(img):
                return img
            self.run(step)
            t += step
        raise AssertionError(f"condition not reached in {limit} s: {self.ctl.input_image()}")

    def write(self, flags: CmdFlag = C.NONE, width: float | None = None, speed: float | None = None,
              force: int | None = None, if_flags: int | None = None) -> InputImage:
        o = self.ctl.output_image
        self.ctl.write_outputs(OutputImage(
            flags, o.if_flags if if_flags is None else if_flags,
            o.width if width is None else round(width * 100),
            o.speed if speed is None else round(speed * 100),
            o.force_limit if force is None else force))
        return self.ctl.input_image()

    def pulse(self, flag: CmdFlag, **kw: float | int) -> InputImage:
        img = self.write(flag, **kw)  # type: ignore[arg-type]
        self.write(C.NONE)
        return img

    def home(self) -> None:
        self.pulse(C.HOMING)
        self.until(lambda i: i.state == GS.IDLE and bool(i.sysstate & SF.SF_REFERENCED))

    def settle(self) -> InputImage:
        return self.until(lambda i: not i.sysstate & SF.SF_MOVING and i.status != Status.E_CMD_PENDING)


@pytest.fixture
def rig() -> Rig:
    r = Rig()
    r.home()
    return r


def test_homing_edge_pending_positioning_then_referenced() -> None:
    r = Rig()
    img = r.ctl.input_image()
    assert img.state == GS.IDLE and not img.sysstate & SF.SF_REFERENCED
    img = r.write(C.HOMING)
    assert img.status == Status.E_CMD_PENDING and img.state == GS.POSITIONING   # 002 §4.4
    img = r.until(lambda i: i.status != Status.E_CMD_PENDING)
    assert img.status == Status.E_SUCCESS and img.state == GS.IDLE and img.sysstate & SF.SF_REFERENCED


def test_move_before_homing_is_refused() -> None:
    r = Rig()
    img = r.write(C.MOVE, width=30, speed=100)
    assert img.status == Status.E_NOT_INITIALIZED and img.state == GS.IDLE


def test_move_positions_with_fresh_width_on_every_read(rig: Rig) -> None:
    img = rig.write(C.MOVE, width=30, speed=400, force=0)
    assert img.status == Status.E_CMD_PENDING and img.state == GS.POSITIONING
    widths = []
    for _ in range(5):
        rig.run(0.05)
        widths.append(rig.ctl.input_image().width)
    assert widths == sorted(widths, reverse=True) and len(set(widths)) == 5   # WIDTH fresh, closing
    img = rig.settle()
    assert img.status == Status.E_SUCCESS and img.state == GS.IDLE and img.width == 3000
    assert rig.ctl.input_image().status == Status.E_SUCCESS   # STATUS holds


def test_flag_held_high_does_not_fire_again(rig: Rig) -> None:
    rig.write(C.MOVE, width=50, speed=400)
    rig.settle()
    rig.write(C.MOVE, width=50, speed=400)           # still 1: no edge
    assert rig.ctl.input_image().status == Status.E_SUCCESS
    rig.write(C.NONE)
    assert rig.write(C.MOVE, width=40, speed=400).status == Status.E_CMD_PENDING


def test_grip_holding_with_force_then_release(rig: Rig) -> None:
    rig.pulse(C.MOVE, width=30, speed=400)
    rig.settle()
    rig.g.faults.place_part(22.0)
    img = rig.pulse(C.GRIP, width=22, speed=400, force=5000)
    assert img.state == GS.GRIPPING and img.status == Status.E_CMD_PENDING
    img = rig.settle()
    assert img.state == GS.HOLDING and img.status == Status.E_SUCCESS
    assert img.force_n() == pytest.approx(50.0, abs=1.0)
    assert abs(img.width_mm - 22.0) < 0.5
    img = rig.pulse(C.RELEASE, width=30, speed=400)
    assert img.state == GS.RELEASING and img.status == Status.E_CMD_PENDING
    img = rig.settle()
    assert img.state == GS.IDLE and img.status == Status.E_SUCCESS and img.width == 3000


def test_grip_without_part_is_no_part_and_cmd_failed(rig: Rig) -> None:
    rig.pulse(C.MOVE, width=30, speed=400)
    rig.settle()
    rig.pulse(C.GRIP, width=22, speed=400, force=5000)
    img = rig.settle()
    assert img.state == GS.NO_PART and img.status == Status.E_CMD_FAILED


def test_lowest_bit_wins(rig: Rig) -> None:
    img = rig.write(C.MOVE | C.GRIP, width=30, speed=400, force=5000)
    assert img.state == GS.POSITIONING                 # MOVE, not GRIP
    rig.settle()
    rig.write(C.NONE)
    img = rig.write(C.RELEASE | C.HOMING, width=60, speed=400)
    assert img.state == GS.RELEASING                   # RELEASE (bit 2) before HOMING (bit 3)


def test_faststop_edge_is_never_lost(rig: Rig) -> None:
    img = rig.write(C.MOVE | C.FASTSTOP, width=30, speed=400)
    assert img.sysstate & SF.SF_FAST_STOP and not img.sysstate & SF.SF_MOVING
    assert img.status == Status.E_SUCCESS


def test_faststop_during_motion_then_ack_rules(rig: Rig) -> None:
    rig.write(C.MOVE, width=20, speed=400)
    rig.run(0.05)
    img = rig.write(C.FASTSTOP)
    # 002 §4.6 / 003 §5.6: "The gripper state is set to IDLE", also when a motion was cut
    assert img.sysstate & SF.SF_FAST_STOP and img.state == GS.IDLE and img.status == Status.E_SUCCESS
    # motion refused while FAST STOP is pending
    rig.write(C.NONE)
    assert rig.write(C.MOVE, width=50, speed=400).status == Status.E_ACCESS_DENIED
    # STOP/ACK while FASTSTOP is still 1: refused, FAST STOP stays
    rig.write(C.FASTSTOP)
    img = rig.write(C.FASTSTOP | C.STOP_ACK)
    assert img.status == Status.E_ACCESS_DENIED and img.sysstate & SF.SF_FAST_STOP
    # reset FASTSTOP first, then a fresh STOP/ACK edge acknowledges; gripper state IDLE (002 §4.5)
    rig.write(C.NONE)
    img = rig.write(C.STOP_ACK)
    assert not img.sysstate & SF.SF_FAST_STOP and img.state == GS.IDLE and img.status == Status.E_SUCCESS
    assert img.sysstate & SF.SF_AXIS_STOPPED


@pytest.mark.parametrize("held", [C.STOP_ACK, C.FASTSTOP])
def test_motion_disabled_while_stop_or_faststop_held(rig: Rig, held: CmdFlag) -> None:
    rig.write(held)
    if held == C.FASTSTOP:
        rig.write(C.NONE)
        rig.write(C.STOP_ACK)      # acknowledge, then hold FASTSTOP at 1 again without a new edge
        rig.write(C.NONE)
        rig.ctl.output_image = OutputImage(C.FASTSTOP)
    img = rig.write(held | C.MOVE, width=40, speed=400)
    assert img.status == Status.E_ACCESS_DENIED and not img.sysstate & SF.SF_MOVING


def test_stop_during_motion(rig: Rig) -> None:
    rig.write(C.MOVE, width=10, speed=400)
    rig.run(0.05)
    img = rig.write(C.MOVE | C.STOP_ACK)
    assert img.status == Status.E_SUCCESS and img.state == GS.IDLE
    assert img.sysstate & SF.SF_AXIS_STOPPED and not img.sysstate & SF.SF_FAST_STOP
    rig.run(0.1)
    assert rig.ctl.input_image().status == Status.E_SUCCESS   # the aborted MOVE's final does not overwrite


@pytest.mark.parametrize(("flag", "width", "speed", "force"), [
    (C.MOVE, 120.0, 100.0, 0),        # beyond the 110 mm stroke
    (C.MOVE, -1.0, 100.0, 0),
    (C.MOVE, 30.0, 500.0, 0),         # beyond 420 mm/s
    (C.MOVE, 30.0, 0.0, 0),           # speed 0 is not allowed outside jog
    (C.MOVE, 30.0, 100.0, 9000),      # 90 N beyond the nominal 80 N
    (C.GRIP, 20.0, 100.0, 0),         # no force
    (C.GRIP, 20.0, 100.0, 10000),
    (C.RELEASE, 200.0, 100.0, 0),
])
def test_parameters_beyond_limits_raise_fast_stop(rig: Rig, flag: CmdFlag, width: float, speed: float,
                                                  force: int) -> None:
    img = rig.write(flag, width=width, speed=speed, force=force)
    assert img.sysstate & SF.SF_FAST_STOP and img.status == Status.E_RANGE_ERROR
    assert not img.sysstate & SF.SF_MOVING


@pytest.mark.parametrize("param", ["width", "speed", "force"])
def test_parameter_change_while_moving_raises_fast_stop(rig: Rig, param: str) -> None:
    rig.write(C.MOVE, width=20, speed=300, force=4000)
    rig.run(0.05)
    kw: dict[str, float | int] = {"width": 21.0, "speed": 310.0, "force": 4100}
    img = rig.write(C.MOVE, **{param: kw[param]})  # type: ignore[arg-type]
    # a FAST STOP from any source sets the gripper state to IDLE (002 §4.6 / 003 §5.6)
    assert img.sysstate & SF.SF_FAST_STOP and img.state == GS.IDLE and img.status == Status.E_CMD_ABORTED


def test_parameter_change_while_idle_is_fine(rig: Rig) -> None:
    img = rig.write(C.NONE, width=12.34, speed=56, force=789)
    assert not img.sysstate & SF.SF_FAST_STOP


def test_jog_levels(rig: Rig) -> None:
    rig.pulse(C.MOVE, width=50, speed=400)
    rig.settle()
    img = rig.write(C.JOG_PLUS, speed=20, force=0)
    assert img.status == Status.E_CMD_PENDING
    rig.run(0.5)
    img = rig.ctl.input_image()
    assert img.state == GS.RELEASING and img.sysstate & SF.SF_MOVING and img.width > 5500
    w = img.width
    img = rig.write(C.JOG_PLUS | C.JOG_MINUS)          # 11: stop
    rig.run(0.3)
    img = rig.ctl.input_image()
    assert not img.sysstate & SF.SF_MOVING and abs(img.width - w) < 200
    img = rig.write(C.JOG_MINUS)                       # 01: negative
    rig.run(0.5)
    assert rig.ctl.input_image().width < w - 300
    img = rig.write(C.NONE)                            # 00 after jogging: stop, jog mode left
    rig.run(0.3)
    img = rig.ctl.input_image()
    assert not img.sysstate & SF.SF_MOVING and img.status == Status.E_SUCCESS and img.state == GS.IDLE


def test_jog_speed_zero_means_minimum_speed(rig: Rig) -> None:
    rig.pulse(C.MOVE, width=50, speed=400)
    rig.settle()
    rig.write(C.JOG_MINUS, speed=0, force=0)
    rig.run(1.0)
    moved = 50.0 - rig.ctl.input_image().width_mm
    assert 3.0 < moved <= 5.01   # minimum speed of the WSG 50: 5 mm/s
    rig.write(C.NONE)


def test_jog_to_the_end_reports_success_and_is_refused_under_fast_stop(rig: Rig) -> None:
    rig.write(C.JOG_PLUS, speed=400, force=0)
    img = rig.until(lambda i: not i.sysstate & SF.SF_MOVING, limit=3)
    assert img.status == Status.E_SUCCESS and img.width == 11000
    rig.write(C.NONE)
    rig.pulse(C.FASTSTOP)
    img = rig.write(C.JOG_MINUS, speed=10)
    assert img.status == Status.E_ACCESS_DENIED and not img.sysstate & SF.SF_MOVING


def test_jog_speed_beyond_limit_raises_fast_stop(rig: Rig) -> None:
    img = rig.write(C.JOG_MINUS, speed=600, force=0)
    assert img.sysstate & SF.SF_FAST_STOP and img.status == Status.E_RANGE_ERROR


def test_user_flags_go_to_and_come_from_scripts(rig: Rig) -> None:
    rig.write(C.NONE, if_flags=0xA5)
    assert rig.g.script_if == 0xA5
    rig.g.set_script_of(0x3C)
    assert rig.ctl.input_image().of_flags == 0x3C


def test_wsg70_force_unit_in_both_directions() -> None:
    r = Rig("wsg70")
    assert r.ctl.force_scale == 10
    r.home()
    r.pulse(C.MOVE, width=60, speed=200)
    r.settle()
    r.g.faults.place_part(40.0)
    r.pulse(C.GRIP, width=40, speed=200, force=1500)     # 150.0 N in 1/10 N
    img = r.settle()
    assert img.state == GS.HOLDING
    assert img.force == pytest.approx(1500, abs=20) and img.force_n("wsg70") == pytest.approx(150, abs=2)
    # 1500 in 1/100 N would be 15 N; 2500 (250 N) is beyond the WSG 70's nominal 200 N
    r.pulse(C.RELEASE, width=60, speed=200)
    r.settle()
    img = r.write(C.GRIP, width=40, speed=200, force=2500)
    assert img.status == Status.E_RANGE_ERROR and img.sysstate & SF.SF_FAST_STOP
