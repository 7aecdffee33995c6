"""The soft PLC (002 Appendix D SCL listing) after a FAST STOP, deterministic on the manual clock.

A FAST STOP sets the gripper state to IDLE, not ERROR (002 §4.6, 003 §5.6), and the listing leaves
its steps only on ``STW1.ERROR``. Taken literally (the default) it waits for ever when the FAST STOP
strikes in a step that waits for GRASPING/HOLDING (step 7 while GRIPPING) and says why. With
``recover_fast_stop`` (``wsg plc-demo --recover-fast-stop``) the port treats ``SYSSTATE.FAST_STOP``
like ERROR, so it goes to the listing's error step −1 (STOP/ACK acknowledges, 002 §4.5), homes and
grips again (docs/fidelity.md, "The SCL listing after a FAST STOP").
"""

from __future__ import annotations

from collections.abc import Callable

import pytest

from pywsg.fieldbus.plc import GrippingCycle
from pywsg.protocol import CATALOG, Command, Frame, GripperState

from .test_controller import Rig

GS = GripperState
SCAN = 0.002  # s, as `wsg plc-demo`


class PlcRig(Rig):
    """Virtual gripper with a 22 mm part, the fieldbus controller and the soft PLC, on one manual clock."""

    def __init__(self, recover: bool = True) -> None:
        super().__init__()
        self.g.faults.place_part(22.0)
        self.log: list[str] = []
        self.cyc = GrippingCycle(log=self.log.append, recover_fast_stop=recover)
        self.visited: list[int] = []

    def advance(self, dt: float) -> None:
        """Let the gripper run ``dt`` s without a PLC scan."""
        self.run(dt)

    def scan(self) -> None:
        """One PLC scan: read the inputs, run the CASE, write changed outputs; then one scan time passes."""
        out = self.cyc.step(self.ctl.input_image(), self.clock.now)
        if out != self.ctl.output_image:
            self.ctl.write_outputs(out)
        if not self.visited or self.visited[-1] != self.cyc.state:
            self.visited.append(self.cyc.state)
        self.advance(SCAN)

    def scan_until(self, done: Callable[[], bool], limit: float = 15.0) -> None:
        end = self.clock.now + limit
        while not done():
            assert self.clock.now < end, f"stuck in step {self.cyc.state}:\n" + "\n".join(self.log[-12:])
            self.scan()

    def gstate(self) -> GripperState:
        return self.ctl.gripper_state()


def _faststop_23h(rig: PlcRig) -> None:
    """FAST STOP from the binary interface (23h on another session), as `wsg fast-stop` would."""
    session = rig.g.open_session("tcp", peer="operator")
    rig.g.handle_frame(session, Frame(int(Command.FAST_STOP), CATALOG[Command.FAST_STOP].encode_request({})))


def _power_fault(rig: PlcRig) -> None:
    """The scenario's fault: supply voltage fault (App. B SF_POWER_FAULT) for 2 s."""
    rig.g.faults.power_fault(True)
    end = rig.clock.now + 2.0
    rig.scan_until(lambda: rig.clock.now >= end)
    rig.g.faults.power_fault(False)


@pytest.mark.parametrize("cause", [_power_fault, _faststop_23h], ids=["power-fault", "23h"])
@pytest.mark.parametrize(("step", "gstate"), [
    (6, GS.HOLDING),      # the report: the grip finished before the PLC's next scan
    (7, GS.GRIPPING),     # GRASPING seen, HOLDING not yet: the hold timer never starts
    (7, GS.HOLDING),      # holding, timer running
    (11, GS.POSITIONING),  # back to the start width
])
def test_fast_stop_in_any_step_goes_through_the_error_step_and_grips_again(
        step: int, gstate: GripperState, cause: Callable[[PlcRig], None]) -> None:
    """002 App. D + §4.6: whatever step the FAST STOP catches, the cycle acknowledges it and goes on."""
    rig = PlcRig()
    rig.scan_until(lambda: rig.cyc.holds >= 1)              # homed, one part held
    rig.scan_until(lambda: rig.cyc.state == step and (step == 6 or rig.gstate() == gstate))
    if step == 6:
        rig.advance(0.0)
        while rig.gstate() != gstate:                        # the gripper is faster than the PLC's scan
            rig.advance(0.001)
    holds, errors = rig.cyc.holds, rig.cyc.error_count
    rig.visited.clear()
    cause(rig)
    rig.scan_until(lambda: rig.cyc.holds > holds)          # hung here before (steps 6 and 7)
    assert -1 in rig.visited and rig.cyc.error_count > errors   # through the listing's error step
    assert rig.visited.index(-1) < rig.visited.index(0) < rig.visited.index(2)   # STOP/ACK, then homing
    assert rig.gstate() in (GS.GRIPPING, GS.HOLDING) and not rig.g.snapshot().fast_stop


def test_a_lasting_fault_is_logged_once_not_per_scan() -> None:
    """While the power fault refuses the acknowledge, -1 -> 0 -> 1 -> -1 repeats every 3 scans (the
    listing's own loop); the log shows it once and the count when it ends."""
    rig = PlcRig()
    rig.scan_until(lambda: rig.cyc.holds >= 1)
    rig.scan_until(lambda: rig.cyc.state == 7 and rig.gstate() == GS.HOLDING)
    before = len(rig.log)
    _power_fault(rig)                                       # 2 s = 1000 scans
    rig.scan_until(lambda: rig.cyc.state == 2)
    during = rig.log[before:]
    assert len(during) < 12, during
    assert any("repeated" in line for line in during)


def test_the_listing_exactly_waits_for_ever_after_a_fast_stop_while_gripping() -> None:
    """002 App. D taken literally (the default): step 7 starts its hold timer only on HOLDING and leaves
    only on ERROR / NO_PART / PART_LOST; a FAST STOP while GRIPPING shows IDLE (002 §4.6), so it stays
    in step 7. ``fast_stop_hint`` says so; it is None while the cycle runs normally."""
    rig = PlcRig(recover=False)
    rig.scan_until(lambda: rig.cyc.holds >= 1)
    assert rig.cyc.fast_stop_hint(rig.ctl.input_image()) is None
    rig.scan_until(lambda: rig.cyc.state == 7 and rig.gstate() == GS.GRIPPING)
    _faststop_23h(rig)
    end = rig.clock.now + 5.0
    rig.scan_until(lambda: rig.clock.now >= end)             # 2,500 scans
    assert rig.cyc.state == 7 and rig.gstate() == GS.IDLE and rig.g.snapshot().fast_stop
    assert rig.cyc.error_count == 0 and rig.cyc.holds == 1
    hint = rig.cyc.fast_stop_hint(rig.ctl.input_image())
    assert hint is not None and "step 7" in hint and "--recover-fast-stop" in hint and "002 §4.6" in hint


def test_the_listing_exactly_leaves_through_a_refused_command_where_it_can() -> None:
    """Without the option a FAST STOP while the fingers pre-position (step 5 after POSITIONING was seen)
    is left through the port's refused-command check: GRIP is refused (E_ACCESS_DENIED), step 6 goes to
    the listing's error step −1, which acknowledges; the cycle grips again."""
    rig = PlcRig(recover=False)
    rig.scan_until(lambda: rig.cyc.holds >= 1)
    rig.scan_until(lambda: rig.cyc.state == 4 and rig.gstate() == GS.POSITIONING)
    rig.scan()                                              # step 4 sees POSITIONING: on to step 5
    rig.visited.clear()
    _faststop_23h(rig)
    rig.scan_until(lambda: rig.cyc.holds > 1)
    assert -1 in rig.visited and rig.cyc.error_count == 1
