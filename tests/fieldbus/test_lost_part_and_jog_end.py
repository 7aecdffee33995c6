"""The fieldbus after a lost part and at the end of jog (issue 24 items 2, 3, 5), on the manual clock.

- 002 App. D step 7: "No part found or part lost. Go to next step": the vendor's SCL listing, run by
  ``GrippingCycle`` (``wsg plc-demo``), must take its normal path when the part is lost while HOLDING,
  whenever that happens in the hold time — no FAST STOP from 002 §3.1 ("Changing parameters while
  fingers are moving … will result in a FAST STOP"), no error recovery.
- 002 §4.7 / 003 §5.7: "If the Jog flags change to both 0, the Jog mode is left and the drive is stopped."
"""

from __future__ import annotations

import pytest

from pywsg.fieldbus.image import CmdFlag
from pywsg.protocol import GripperState, Status, SystemFlag

from .test_controller import Rig
from .test_plc_fast_stop import PlcRig

GS = GripperState
C = CmdFlag
SF = SystemFlag


@pytest.mark.parametrize("into_hold", [0.0, 0.5, 0.99], ids=["at-once", "mid-hold", "as-the-timer-ends"])
def test_the_listing_takes_its_normal_path_after_a_lost_part(into_hold: float) -> None:
    """The part goes ``into_hold`` s after HOLDING (hold time 1 s): step 7 sees PART_LOST and goes to
    step 8 (RELEASE), the image never shows FAST STOP or STATUS E_CMD_ABORTED (19), the cycle goes on
    and grips the next part; no error recovery."""
    rig = PlcRig(recover=False)
    rig.scan_until(lambda: rig.cyc.holds >= 1)
    rig.scan_until(lambda: rig.cyc.state == 7 and rig.gstate() == GS.HOLDING)
    end = rig.clock.now + into_hold
    rig.scan_until(lambda: rig.clock.now >= end)
    rig.visited.clear()
    rig.g.faults.remove_part()
    img = rig.ctl.input_image()
    assert img.state == GS.PART_LOST and not img.sysstate & SF.SF_MOVING
    seen_status: set[int] = set()
    seen_fast_stop = False

    def next_grip() -> bool:
        nonlocal seen_fast_stop
        image = rig.ctl.input_image()
        seen_status.add(image.status)
        seen_fast_stop |= bool(image.sysstate & SF.SF_FAST_STOP)
        return rig.cyc.state == 6

    rig.g.faults.place_part(22.0)  # the next part, for the next cycle
    rig.scan_until(next_grip)
    assert rig.visited[:3] in ([7, 8, 9], [8, 9, 10]), rig.visited
    assert -1 not in rig.visited and rig.cyc.error_count == 0
    assert not seen_fast_stop and Status.E_CMD_ABORTED not in seen_status
    rig.scan_until(lambda: rig.cyc.holds >= 2)


def _jog_into_obstacle(rig: Rig) -> None:
    rig.home()
    rig.g.faults.block_at(50.0)
    rig.write(C.JOG_MINUS, speed=100.0, force=3000)  # 30.00 N
    rig.run(2.0)


def test_a_blocked_jog_is_finished_while_the_flag_is_held() -> None:
    """002 §4.7: "When the end position is reached (or in case of an error), the gripper state is set to
    IDLE"; STATUS is the command's result when it has finished: E_SUCCESS, BLOCKED_MINUS, FORCE 30 N
    (the jog's force) while JOG- is still 1 (docs/fidelity.md "Jog error")."""
    rig = Rig()
    _jog_into_obstacle(rig)
    img = rig.ctl.input_image()
    assert img.state == GS.IDLE and img.status == Status.E_SUCCESS
    assert img.sysstate & SF.SF_BLOCKED_MINUS and not img.sysstate & SF.SF_MOVING
    assert img.width == 5000 and img.force == 3000  # 50.00 mm, 30.00 N


def test_jog_end_stops_the_drive() -> None:
    """002 §4.7 / 003 §5.7: both jog flags back to 0 → the drive is stopped: FORCE 0.00 N and
    BLOCKED_MINUS cleared in the image, 45h reads 0 N, 41h IDLE — with the obstacle still there."""
    rig = Rig()
    _jog_into_obstacle(rig)
    img = rig.write(C.NONE)
    assert img.force == 0 and not img.sysstate & SF.SF_BLOCKED_MINUS
    assert img.state == GS.IDLE and img.status == Status.E_SUCCESS
    rig.run(1.0)
    img = rig.ctl.input_image()
    assert img.force == 0 and img.width == 5000 and rig.g.force() == 0.0
    assert rig.g.obstacles.get("block") is not None
