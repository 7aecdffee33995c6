"""Run the node: ``wsg ros``, ``ros2 run pywsg_ros wsg_node``, or the launch file.

The executor spins on a thread of its own; the main thread waits for SIGINT, SIGTERM or SIGHUP, then
deactivates the node (the gripper is released with its disconnect announcement, so no FAST STOP),
stops the executor and joins its thread, and only then shuts rclpy down (rclpy aborts the process when
it is shut down under a running executor)."""

from __future__ import annotations

import signal
import sys
import threading
from collections.abc import Sequence

import rclpy
from rclpy.executors import MultiThreadedExecutor
from rclpy.parameter import Parameter

from .node import SUCCESS, WsgNode

#: executor threads: one goal, the services, diagnostics and the lifecycle services at once
THREADS = 4


def main(args: Sequence[str] | None = None, *, url: str | None = None, node_name: str = "wsg_gripper") -> int:
    """Run a :class:`WsgNode` until a signal; ``args``: ROS arguments (``--ros-args -p speed:=50.0 ...``);
    ``url`` overrides the ``url`` parameter. Returns the exit status."""
    init = {"args": list(sys.argv if args is None else args)}
    try:
        from rclpy.signals import SignalHandlerOptions

        init_options = {**init, "signal_handler_options": SignalHandlerOptions.NO}
        rclpy.init(**init_options)  # our own handlers below: an orderly release first
    except ImportError:  # pragma: no cover - before Humble
        rclpy.init(**init)
    stop = threading.Event()
    for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
        signal.signal(sig, lambda *_: stop.set())
    overrides = [Parameter("url", value=url)] if url else []
    node = WsgNode(node_name, parameter_overrides=overrides)
    executor = MultiThreadedExecutor(num_threads=THREADS)
    executor.add_node(node)
    spinner = threading.Thread(target=executor.spin, name="wsg-ros-executor", daemon=True)
    spinner.start()
    status = 0
    try:
        if node.settings.autostart and not (node.trigger_configure() == SUCCESS
                                            and node.trigger_activate() == SUCCESS):
            node.get_logger().error(f"could not start on {node.settings.url}")
            status = 1
            stop.set()
        while not stop.wait(0.5):
            pass
    finally:
        try:
            node.trigger_shutdown()  # releases the gripper (07h) from any primary state
        except Exception:
            node.on_cleanup(None)
        executor.shutdown()
        spinner.join(5)
        node.destroy_node()
        rclpy.try_shutdown()
    return status
