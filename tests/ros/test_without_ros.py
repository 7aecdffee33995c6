"""Where ROS 2 is missing: ``wsg ros`` says so clearly; ``import pywsg`` and the driver never need it."""

from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.skipif(importlib.util.find_spec("rclpy") is not None, reason="rclpy is installed here")


def test_wsg_ros_without_rclpy_says_what_to_do() -> None:
    wsg = Path(sys.executable).with_name("wsg")
    out = subprocess.run([str(wsg), "ros", "--url", "tcp://127.0.0.1:9"],
                         capture_output=True, text=True, timeout=60)
    assert out.returncode == 1
    assert "needs ROS 2" in out.stderr and "docs/ros.md" in out.stderr
    assert "Traceback" not in out.stderr


def test_pywsg_ros_import_names_rclpy() -> None:
    with pytest.raises(ImportError, match="rclpy") as err:
        importlib.import_module("pywsg.ros")
    assert err.value.name == "rclpy"
