"""std_srvs/Trigger services, /diagnostics, and wsg50-ros-pkg's services and status topic, from a second
rclpy process, against the virtual WSG (000 §3.2.1 homing, §3.2.3 stop, §3.2.4 FAST STOP, §3.2.5
acknowledge, §3.4.1 system flags)."""

from __future__ import annotations

import pytest

from .conftest import rig_fixture
from .rig import Rig, needs_ros

pytestmark = needs_ros

ERROR, OK = 2, 0


rig = rig_fixture("ros-services")


@pytest.fixture(autouse=True)
def ready(rig: Rig) -> None:
    rig.call("wait")


def test_homing_stop_fast_stop_and_acknowledge(rig: Rig) -> None:
    out = rig.call("trigger", name="homing")
    assert out["success"], out
    assert rig.world.state()["width"] == pytest.approx(110.0, abs=0.01)  # the default homing opens
    assert rig.call("trigger", name="stop")["success"]
    assert rig.call("trigger", name="fast_stop")["success"]
    assert rig.world.state()["fast_stop"]
    # motion is refused while in FAST STOP: the goal is aborted, and the diagnostics say why
    assert rig.call("goal", position=0.05)["aborted"]
    diag = rig.call("diag", contains="SF_FAST_STOP", level=ERROR)["status"]
    assert "SF_FAST_STOP" in diag["message"]
    assert "E_ACCESS_DENIED" in diag["values"]["last_error"] or "FAST" in diag["values"]["last_error"].upper()
    assert rig.call("trigger", name="acknowledge")["success"]
    assert not rig.world.state()["fast_stop"]
    rig.call("diag", absent="SF_FAST_STOP", level=OK)
    assert rig.call("goal", position=0.05)["succeeded"]


def test_diagnostics_report_a_fault_placed_in_the_world(rig: Rig) -> None:
    rig.world.fault("power")
    try:
        diag = rig.call("diag", contains="SF_POWER_FAULT", level=ERROR)["status"]
        assert diag["hardware_id"] and diag["values"]["temperature_c"]
        float(diag["values"]["temperature_c"])
        # the acknowledge is refused while the fault persists, and says which fault
        refused = rig.call("trigger", name="acknowledge")
        assert not refused["success"] and "POWER" in refused["message"].upper()
    finally:
        rig.world.fault("power", on=False)
    rig.call("trigger", name="acknowledge")
    rig.call("diag", absent="SF_POWER_FAULT", level=OK)
    rig.world.heat(40)  # the temperature the diagnostics show follows the gripper's
    diag = rig.call("diag", key="temperature_c", contains="")["status"]
    assert float(diag["values"]["temperature_c"]) >= rig.world.state()["temperature"] - 1.0
    rig.world.heat(-40)


def test_wsg50_ros_pkg_services_and_status(rig: Rig) -> None:
    assert rig.call("legacy", name="homing")["error"] is None
    assert rig.call("legacy", name="move", width=50.0, speed=200.0)["error"] == 0
    assert rig.world.state()["width"] == pytest.approx(50.0, abs=0.01)
    assert rig.call("legacy", name="move", width=200.0, speed=200.0)["error"] == 255  # outside the stroke
    assert rig.call("legacy", name="move_incrementally", direction="open", increment=5.0)["error"] == 0
    assert rig.world.state()["width"] == pytest.approx(55.0, abs=0.05)
    assert rig.call("legacy", name="set_force", val=25.0)["error"] == 0
    assert rig.call("legacy", name="set_acceleration", val=800.0)["error"] == 0
    rig.world.place_part(20)
    try:
        assert rig.call("legacy", name="grasp", width=20.0, speed=200.0)["error"] == 0
        assert rig.world.state()["gripper_state"] == "HOLDING"
        assert rig.world.state()["force"] == pytest.approx(25.0, abs=0.5)  # set_force took
        status = rig.call("status")["status"]
        assert status["status"] == "HOLDING" and status["width"] == pytest.approx(20.0, abs=0.1)
        assert status["acc"] == pytest.approx(800.0, abs=1.0)
        assert rig.call("legacy", name="release", width=60.0, speed=200.0)["error"] == 0
    finally:
        rig.world.remove_part()
    # no part: grasp answers the gripper's status code (E_CMD_FAILED), as the ROS 1 driver did
    assert rig.call("legacy", name="grasp", width=20.0, speed=200.0)["error"] == 18
    assert rig.call("legacy", name="stop")["error"] is None
    rig.call("trigger", name="fast_stop")
    assert rig.call("legacy", name="ack")["error"] is None
    assert not rig.world.state()["fast_stop"]


def test_acceleration_and_force_limit_parameters_reach_the_gripper(rig: Rig) -> None:
    """Set at once on the gripper (30h, 32h): the status topic reads the acceleration back (31h), a grip
    holds with the force limit; a value outside the declared range is refused."""
    rig.call("trigger", name="homing")
    assert rig.call("set_param", name="acceleration", value=900.0)["successful"]
    # the status topic reads it back (31h) at its own rate: a message already on its way carries the old value
    acc = [rig.call("status")["status"]["acc"] for _ in range(3)]
    assert acc[-1] == pytest.approx(900.0, abs=1.0), acc
    assert rig.call("set_param", name="force_limit", value=35.0)["successful"]
    rig.world.place_part(20)
    try:
        assert rig.call("legacy", name="grasp", width=20.0, speed=200.0)["error"] == 0
        assert rig.world.state()["force"] == pytest.approx(35.0, abs=0.5)
        assert rig.call("legacy", name="release", width=60.0, speed=200.0)["error"] == 0
    finally:
        rig.world.remove_part()
    assert not rig.call("set_param", name="joint_state_rate", value=500.0)["successful"]  # above 100 Hz
