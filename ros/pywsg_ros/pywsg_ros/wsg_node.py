"""``ros2 run pywsg_ros wsg_node [--ros-args ...]``: the WSG gripper node (pywsg.ros)."""

import sys


def main() -> None:
    try:
        from pywsg.ros import main as run
    except ImportError as exc:
        sys.exit(f"wsg_node: {exc}; install pywsg into ROS's Python: pip install pywsg (docs/ros.md)")
    sys.exit(run(sys.argv))


if __name__ == "__main__":
    main()
