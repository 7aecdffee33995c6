"""ROS 2 front end: a managed (lifecycle) node that drives a WSG through :class:`pywsg.client.Gripper`.

Importable only where ROS 2's ``rclpy`` is (a sourced ROS 2 installation, or the ROS wheels of
``scripts/ros-env.sh``); ``pip install pywsg`` never pulls ROS. Start it with ``wsg ros --url URL``,
``ros2 run pywsg_ros wsg_node`` or ``ros2 launch pywsg_ros wsg.launch.py`` (docs/ros.md).

The node translates between ROS interfaces and the driver's methods; it holds no protocol logic and
no second state machine (the gripper's own state decides a goal's result).
"""

from __future__ import annotations

import importlib.util

if importlib.util.find_spec("rclpy") is None:  # pragma: no cover - depends on the environment
    raise ImportError(
        "pywsg.ros needs ROS 2's rclpy: source your ROS 2 installation first "
        "(e.g. 'source /opt/ros/jazzy/setup.bash'); see docs/ros.md", name="rclpy")

from .main import main
from .node import WsgNode

__all__ = ["WsgNode", "main"]
