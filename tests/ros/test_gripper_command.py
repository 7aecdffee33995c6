"""control_msgs/action/GripperCommand and joint_states, from a second rclpy process, against the
virtual WSG: open, grip a placed part (stalled at it, with its force), no part (not reached), a cancel
mid-motion (the fingers stop), joint states streaming while a goal runs (000 §3.2, §3.4.2)."""

from __future__ import annotations

import pytest

from .conftest import rig_fixture
from .rig import Rig, needs_ros, wait_until

pytestmark = needs_ros


rig = rig_fixture("ros-action")


@pytest.fixture(autouse=True)
def ready(rig: Rig) -> None:
    """Each test starts referenced, at 60 mm, with no part and full speed."""
    rig.call("wait")
    rig.world.remove_part()
    if rig.world.state()["gripper_state"] != "IDLE" or abs(rig.world.state()["width"] - 60) > 0.01:
        assert rig.call("trigger", name="homing")["success"]
        assert rig.call("goal", position=0.06)["succeeded"]
    assert rig.call("set_param", name="speed", value=400.0)["successful"]


def test_open_reaches_the_goal(rig: Rig) -> None:
    out = rig.call("goal", position=0.085)
    assert out["succeeded"] and out["result"]["reached_goal"] and not out["result"]["stalled"]
    assert out["result"]["position"] == pytest.approx(0.085, abs=1e-4)
    assert rig.world.state()["width"] == pytest.approx(85.0, abs=0.01)  # the gripper moved, not only the answer


def test_grip_a_placed_part_is_stalled_with_its_force(rig: Rig) -> None:
    rig.world.place_part(20)
    out = rig.call("goal", position=0.02, max_effort=30.0)
    assert out["succeeded"], out
    assert out["result"]["stalled"] and not out["result"]["reached_goal"]  # HOLDING: stalled at the part
    assert out["result"]["effort"] == pytest.approx(30.0, abs=0.5)  # max_effort became the grip force
    assert out["result"]["position"] == pytest.approx(0.02, abs=2e-4)
    assert rig.world.state()["gripper_state"] == "HOLDING"
    # a wider goal while holding releases the part (26h)
    out = rig.call("goal", position=0.06)
    assert out["succeeded"] and out["result"]["reached_goal"]
    assert rig.world.state()["gripper_state"] != "HOLDING"


def test_grip_without_a_part_is_not_reached(rig: Rig) -> None:
    out = rig.call("goal", position=0.02, max_effort=20.0)
    assert out["aborted"], out
    assert not out["result"]["reached_goal"] and not out["result"]["stalled"]  # NO_PART
    assert rig.world.state()["gripper_state"] == "NO_PART"


def test_cancel_stops_the_fingers_mid_motion(rig: Rig) -> None:
    assert rig.call("set_param", name="speed", value=10.0)["successful"]
    out = rig.call("goal", position=0.1, cancel_after=0.4)  # 60 -> 100 mm at 10 mm/s: 4 s
    assert out["canceled"], out
    width = rig.world.state()["width"]
    assert 60.5 < width < 99.0
    assert not wait_until(lambda: rig.world.state()["width"] > width + 0.05, timeout=0.3)  # stopped, not coasting
    assert out["result"]["position"] == pytest.approx(width / 1000, abs=2e-4)


def test_joint_states_stream_while_a_goal_runs(rig: Rig) -> None:
    assert rig.call("set_param", name="speed", value=50.0)["successful"]
    out = rig.call("goal", position=0.1)  # 60 -> 100 mm at 50 mm/s: 0.8 s
    assert out["succeeded"]
    js = out["joint_states"]
    inside = [p for _, p in js if 0.0301 < p[1] < 0.0499]  # half-openings between the start and the goal
    assert len(inside) >= 5, js  # the stream ran during the motion, not only before and after
    rights = [p[1] for _, p in js]
    assert rights == sorted(rights)  # opening all along
    assert all(left == pytest.approx(-right) for left, right in (p for _, p in js))
    assert len(out["feedback"]) >= 3 and out["feedback"][-1]["position"] > out["feedback"][0]["position"]
    names = rig.call("joint_states", duration=0.2)["names"]
    assert names == ["wsg50_finger_left_joint", "wsg50_finger_right_joint"]
