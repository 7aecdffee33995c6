"""The ROS packages in ros/: wsg_50_common has wsg50-ros-pkg's interface (names, fields, types) and
pywsg_ros is a complete ament_python package. No ROS needed."""

from __future__ import annotations

import ast
import xml.etree.ElementTree as ET
from pathlib import Path

ROS = Path(__file__).resolve().parents[2] / "ros"

#: wsg50-ros-pkg's wsg_50_common interface files (ROS 1): name -> (request fields, response fields)
OLD_INTERFACE = {
    "msg/Status.msg": ([("string", "status"), ("float32", "width"), ("float32", "speed"), ("float32", "acc"),
                        ("float32", "force"), ("float32", "force_finger0"), ("float32", "force_finger1")], None),
    "msg/Cmd.msg": ([("string", "mode"), ("float32", "pos"), ("float32", "speed")], None),
    "srv/Move.srv": ([("float32", "width"), ("float32", "speed")], [("uint8", "error")]),
    "srv/Conf.srv": ([("float32", "val")], [("uint8", "error")]),
    "srv/Incr.srv": ([("string", "direction"), ("float32", "increment")], [("uint8", "error")]),
}


def fields(text: str) -> list[tuple[str, str]]:
    out = []
    for line in text.splitlines():
        line = line.split("#", 1)[0].strip()
        if line:
            kind, name = line.split()[:2]
            out.append((kind, name))
    return out


def test_wsg_50_common_has_the_ros1_interface() -> None:
    pkg = ROS / "wsg_50_common"
    files = sorted(str(p.relative_to(pkg)) for p in pkg.glob("*/*") if p.suffix in (".msg", ".srv"))
    assert files == sorted(OLD_INTERFACE)
    cmake = (pkg / "CMakeLists.txt").read_text()
    for name, (request, response) in OLD_INTERFACE.items():
        parts = (pkg / name).read_text().split("\n---\n")
        assert fields(parts[0]) == request, name
        if response is not None:
            assert len(parts) == 2 and fields(parts[1]) == response, name
        assert f'"{name}"' in cmake  # generated
    root = ET.parse(pkg / "package.xml").getroot()
    assert root.findtext("name") == "wsg_50_common"
    assert root.findtext("member_of_group") == "rosidl_interface_packages"


def test_pywsg_ros_is_an_ament_python_package() -> None:
    pkg = ROS / "pywsg_ros"
    root = ET.parse(pkg / "package.xml").getroot()
    assert root.findtext("name") == "pywsg_ros"
    assert root.find("export/build_type").text == "ament_python"  # type: ignore[union-attr]
    deps = {e.text for e in root.findall("exec_depend")}
    assert {"rclpy", "control_msgs", "sensor_msgs", "std_srvs", "diagnostic_msgs", "wsg_50_common"} <= deps
    assert (pkg / "resource" / "pywsg_ros").exists()
    setup = (pkg / "setup.py").read_text()
    ast.parse(setup)
    assert "wsg_node = pywsg_ros.wsg_node:main" in setup
    for f in ("pywsg_ros/wsg_node.py", "launch/wsg.launch.py"):
        ast.parse((pkg / f).read_text())
    assert "def generate_launch_description" in (pkg / "launch" / "wsg.launch.py").read_text()
    moveit = (pkg / "config" / "moveit_controllers.yaml").read_text()
    assert "type: GripperCommand" in moveit and "action_ns: gripper_cmd" in moveit
