"""The node's ROS parameters: declared with descriptors (type, range, read-only) and read into
:class:`Settings`. Units as the driver's: mm, mm/s, mm/s², N, Hz."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from rcl_interfaces.msg import FloatingPointRange, ParameterDescriptor
from rclpy.node import Node

#: wsg50-ros-pkg's joint names (its URDF names them so)
JOINT_NAMES = ["wsg50_finger_left_joint", "wsg50_finger_right_joint"]


@dataclass
class Settings:
    """The parameters' values (see docs/ros.md, "Parameters")."""

    url: str = "tcp://127.0.0.1:1000"
    joint_state_rate: float = 50.0
    diagnostics_rate: float = 1.0
    feedback_rate: float = 20.0
    speed: float = 100.0
    acceleration: float = 0.0
    force_limit: float = 0.0
    goal_tolerance: float = 0.0005
    joint_names: list[str] = field(default_factory=lambda: list(JOINT_NAMES))
    joint_signs: list[float] = field(default_factory=lambda: [-1.0, 1.0])
    frame_id: str = "wsg50_base_link"
    reconnect: bool = True
    acknowledge_after_reconnect: bool = False
    legacy_namespace: str = "wsg_50_driver"
    timeout: float = 1.0
    autostart: bool = True


#: parameters whose new value takes effect at once (the others at the next configure)
DYNAMIC = frozenset({"speed", "acceleration", "force_limit", "goal_tolerance", "acknowledge_after_reconnect"})

_DESCRIPTIONS: dict[str, tuple[str, tuple[float, float] | None]] = {
    "url": ("gripper address: tcp://HOST[:1000], udp://HOST[:1500], serial:///dev/ttyUSB0?baudrate=115200, "
            "can://...", None),
    "joint_state_rate": ("Hz of joint_states, from the gripper's width, speed and force auto-update streams "
                         "(the WSG streams at most every 10 ms)", (0.1, 100.0)),
    "diagnostics_rate": ("Hz of /diagnostics", (0.05, 10.0)),
    "feedback_rate": ("Hz of GripperCommand feedback while a goal runs", (1.0, 100.0)),
    "speed": ("mm/s of the fingers for GripperCommand goals", (0.1, 1000.0)),
    "acceleration": ("mm/s² set on the gripper at configure (30h); 0 leaves the gripper's own", (0.0, 20000.0)),
    "force_limit": ("N: the gripper's grip force limit, set at configure (32h; the legacy grasp uses it); 0 leaves "
                    "the gripper's own", (0.0, 2000.0)),
    "goal_tolerance": ("m: a goal closer than this to the opening neither grips nor releases", (0.0, 0.01)),
    "joint_names": ("the two finger joints of joint_states (left, right)", None),
    "joint_signs": ("direction of each finger joint (left, right): [-1.0, 1.0] is wsg50-ros-pkg's URDF, [1.0, 1.0] a "
                    "URDF whose joints both open positive (MoveIt's parallel gripper handle)", None),
    "frame_id": ("frame_id of joint_states", None),
    "reconnect": ("reconnect by itself after a lost connection", None),
    "acknowledge_after_reconnect": ("acknowledge a FAST STOP found after a reconnection (opt-in: the WSG raises "
                                    "FAST STOP when a connection drops; acknowledging resumes motion)", None),
    "legacy_namespace": ("namespace of the wsg50-ros-pkg services and status topic; empty: not offered", None),
    "timeout": ("s to wait for an immediate reply from the gripper", (0.05, 30.0)),
    "autostart": ("configure and activate at start (wsg ros, wsg_node); false: wait for a lifecycle manager", None),
}


def declare(node: Node) -> Settings:
    """Declare every parameter on ``node`` (defaults from :class:`Settings`) and return their values."""
    defaults = Settings()
    for name, (text, bounds) in _DESCRIPTIONS.items():
        d = ParameterDescriptor(description=text, read_only=False)
        if bounds is not None:
            d.floating_point_range = [FloatingPointRange(from_value=bounds[0], to_value=bounds[1], step=0.0)]
        if name not in DYNAMIC:
            d.additional_constraints = "takes effect at the next configure"
        node.declare_parameter(name, getattr(defaults, name), d)
    return read(node)


def read(node: Node) -> Settings:
    """The parameters' current values."""
    values: dict[str, Any] = {name: node.get_parameter(name).value for name in _DESCRIPTIONS}
    values["joint_names"] = list(values["joint_names"])
    values["joint_signs"] = [float(v) for v in values["joint_signs"]]
    return Settings(**values)
