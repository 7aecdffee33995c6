"""The managed node's transitions and the reconnection, from a second rclpy process, against the virtual
WSG: configure connects, deactivate releases the gripper with its disconnect announcement (07h: no FAST
STOP, 000 §3.1.2), activate connects again; a dropped connection (the gripper closes it: FAST STOP,
000 §1.4.2) is reconnected, and the FAST STOP found is acknowledged only when opted in."""

from __future__ import annotations

import subprocess
from pathlib import Path

from ..ports import free_port
from .conftest import rig_fixture
from .rig import ROOT, VENV, Domain, Rig, needs_ros, ros_env, wait_until

pytestmark = needs_ros

ERROR, OK, STALE = 2, 0, 3
PARAMS_FILE = ROOT / "ros" / "pywsg_ros" / "config" / "wsg.yaml"


# the package's own parameters file (its url, a real gripper's, loses to wsg ros --url)
rig = rig_fixture("ros-lifecycle", autostart=False, params_file=PARAMS_FILE)


def test_transitions(rig: Rig) -> None:
    rig.call("wait", configured=False)
    assert rig.call("state")["state"] == "unconfigured"
    assert rig.sessions() == 0  # not connected before configure
    out = rig.call("transition", name="configure")
    assert out["success"] and out["state"] == "inactive"
    assert rig.sessions() == 1
    rig.call("wait")
    assert not rig.call("trigger", name="homing")["success"]  # inactive: refused
    assert rig.call("transition", name="activate")["state"] == "active"
    assert rig.call("trigger", name="homing")["success"]
    assert rig.call("goal", position=0.07)["succeeded"]
    out = rig.call("transition", name="deactivate")
    assert out["success"] and out["state"] == "inactive"
    assert wait_until(lambda: rig.sessions() == 0)
    assert not rig.world.state()["fast_stop"]  # released with the disconnect announcement
    assert not rig.call("goal", position=0.05)["accepted"]
    assert "released" in rig.call("diag", key="system_flags", contains="", level=STALE)["status"]["message"]
    assert rig.call("transition", name="activate")["state"] == "active"  # connects again
    assert rig.sessions() == 1
    assert rig.call("goal", position=0.05)["succeeded"]
    assert rig.call("transition", name="deactivate")["state"] == "inactive"
    assert rig.call("transition", name="cleanup")["state"] == "unconfigured"
    assert rig.sessions() == 0 and not rig.world.state()["fast_stop"]
    assert rig.call("transition", name="configure")["state"] == "inactive"
    assert rig.call("transition", name="activate")["state"] == "active"


def test_reconnect_acknowledges_only_when_opted_in(rig: Rig) -> None:
    rig.call("wait", configured=False)
    if rig.call("state")["state"] != "active":
        rig.call("transition", name="configure")
        rig.call("transition", name="activate")
    rig.call("wait")
    # opted out (the default): the FAST STOP the dropped connection raised stays, and the diagnostics show it
    assert rig.call("set_param", name="acknowledge_after_reconnect", value=False)["successful"]
    rig.world.disconnect()
    rig.call("diag", contains="SF_FAST_STOP", level=ERROR)
    assert wait_until(lambda: rig.sessions() == 1)  # reconnected
    assert rig.world.state()["fast_stop"]
    assert rig.call("trigger", name="acknowledge")["success"]
    # opted in: acknowledged after the reconnection, and goals run again
    assert rig.call("set_param", name="acknowledge_after_reconnect", value=True)["successful"]
    rig.world.disconnect()
    assert wait_until(lambda: rig.sessions() == 1 and not rig.world.state()["fast_stop"], timeout=30)
    rig.call("diag", absent="SF_FAST_STOP", level=OK)
    assert rig.call("goal", position=0.06)["succeeded"]


def test_wsg_ros_exits_1_when_the_gripper_is_not_there(tmp_path: Path) -> None:
    port = free_port()  # nothing listens there
    domain = Domain()
    try:
        out = subprocess.run([str(VENV / "bin" / "wsg"), "ros", "--url", f"tcp://127.0.0.1:{port}"],
                             env=ros_env(tmp_path, domain.number), capture_output=True, text=True, timeout=120)
    finally:
        domain.release()
    assert out.returncode == 1, out.stderr
    assert f"cannot connect to tcp://127.0.0.1:{port}" in out.stderr + out.stdout


def test_deactivate_stops_a_running_goal_first(rig: Rig) -> None:
    rig.call("wait", configured=False)
    for step, before in (("configure", "unconfigured"), ("activate", "inactive")):
        if rig.call("state")["state"] == before:
            rig.call("transition", name=step)
    rig.call("wait", active=True)
    rig.call("trigger", name="homing")
    assert rig.call("goal", position=0.06)["succeeded"]
    assert rig.call("set_param", name="speed", value=10.0)["successful"]
    try:
        out = rig.call("goal", position=0.1, deactivate_after=0.4)  # 60 -> 100 mm at 10 mm/s: 4 s
        assert out["aborted"], out
        assert rig.call("state")["state"] == "inactive"
        width = rig.world.state()["width"]
        assert 60.5 < width < 99.0  # stopped on the way (22h), not left running after the release
        assert not wait_until(lambda: rig.world.state()["width"] > width + 0.05, timeout=0.3)
        assert not rig.world.state()["fast_stop"] and rig.sessions() == 0
    finally:
        rig.call("set_param", name="speed", value=400.0)
        rig.call("transition", name="activate")
