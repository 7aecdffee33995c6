"""``wsg ros``: the gripper as a ROS 2 node (pywsg.ros; needs a ROS 2 installation's rclpy)."""

from __future__ import annotations

import sys

import click
from click.core import ParameterSource


@click.command("ros", context_settings={"ignore_unknown_options": True, "allow_extra_args": True})
@click.option("--url", default=None, metavar="URL",
              help="Gripper address (default: wsg's --url / WSG_URL); the node's 'url' parameter.")
@click.option("--name", "node_name", default="wsg_gripper", show_default=True, help="ROS node name.")
@click.pass_context
def ros(ctx: click.Context, url: str | None, node_name: str) -> None:
    """Run the gripper as a ROS 2 lifecycle node (GripperCommand, joint_states, Trigger services,
    diagnostics, wsg50-ros-pkg's services). Needs ROS 2 (source its setup.bash first); arguments after
    the options go to ROS, e.g. --ros-args -p speed:=50.0 --params-file wsg.yaml. See docs/ros.md."""
    try:
        from ..ros import main
    except ImportError as exc:
        if exc.name not in ("rclpy",) and not str(exc.name or "").endswith("_msgs") and exc.name != "wsg_50_common":
            raise
        raise click.ClickException(
            f"wsg ros needs ROS 2: {exc}. Source a ROS 2 installation with control_msgs "
            "(e.g. 'source /opt/ros/jazzy/setup.bash'; apt install ros-jazzy-control-msgs), "
            "see docs/ros.md") from None
    root = ctx.find_root()
    if url is None and root.get_parameter_source("url") not in (None, ParameterSource.DEFAULT):
        url = root.params["url"]  # wsg --url / WSG_URL given: it beats a parameters file's url
    status = main([sys.argv[0], *ctx.args], url=url, node_name=node_name)
    ctx.exit(status)
