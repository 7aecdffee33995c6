"""The ROS 2 node against the driver alone, in the same run, on one virtual WSG (loopback).

    .venv/bin/python benchmarks/bench_ros.py [--goals 20] [--seconds 3]

Needs the ROS environment of scripts/ros-env.sh (.venv-ros). Prints:

- goal-to-motion latency: from a GripperCommand goal sent by a second rclpy process to the moment the
  virtual gripper's fingers start moving (its gripper state leaves IDLE; observed in this process by
  polling the sim, both sides on CLOCK_MONOTONIC), beside ``Gripper.move(wait=False)`` called in
  this process on a second sim (a WSG takes motion commands from one connection at a time);
  p50, p90, max over ``--goals`` goals each;
- joint_states rate and jitter: messages/s and inter-arrival spread (stdev, p99 - p50) of the node's
  joint_states at joint_state_rate 100 Hz as the client receives them, beside the driver's own width
  auto-update stream (43h at 10 ms) received in this process from the second sim.
"""

from __future__ import annotations

import argparse
import itertools
import os
import statistics
import sys
import threading
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the checkout, for tests/
from pywsg import Gripper
from pywsg.testing import SimThread
from tests.ros.rig import READY, Rig


class MotionWatch:
    """Polls a sim's gripper state on a thread; ``wait_start()``: when it first left IDLE after ``arm()``."""

    def __init__(self, sim: SimThread) -> None:
        self.sim = sim
        self.moving_since: float | None = None
        self._stop = threading.Event()
        self._armed = False
        threading.Thread(target=self._run, daemon=True).start()

    def arm(self) -> None:
        self.moving_since = None
        self._armed = True

    def _run(self) -> None:
        g = self.sim.gripper
        while not self._stop.is_set():
            if self._armed:
                state = self.sim.call(lambda: g.snapshot().gripper_state.name)
                if state != "IDLE":
                    self.moving_since = time.monotonic()
                    self._armed = False
            else:
                time.sleep(0.0005)

    def wait_start(self, timeout: float = 5.0) -> float:
        end = time.monotonic() + timeout
        while self.moving_since is None and time.monotonic() < end:
            time.sleep(0.0005)
        assert self.moving_since is not None, "the fingers never moved"
        return self.moving_since

    def close(self) -> None:
        self._stop.set()


def spread(values: list[float]) -> str:
    v = sorted(values)
    p = lambda q: v[min(len(v) - 1, int(q * len(v)))]  # noqa: E731
    return f"p50 {p(0.5) * 1e3:6.2f} ms  p90 {p(0.9) * 1e3:6.2f} ms  max {v[-1] * 1e3:6.2f} ms"


def intervals(times: list[float]) -> dict[str, float]:
    d = [b - a for a, b in itertools.pairwise(times)]
    d.sort()
    return {"rate": (len(times) - 1) / (times[-1] - times[0]), "mean": statistics.fmean(d),
            "stdev": statistics.pstdev(d), "p50": d[len(d) // 2], "p99": d[min(len(d) - 1, int(0.99 * len(d)))]}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--goals", type=int, default=20)
    ap.add_argument("--seconds", type=float, default=3.0)
    args = ap.parse_args()
    if not READY.exists():
        sys.exit("run scripts/ros-env.sh first (the ROS 2 environment in .venv-ros)")
    import tempfile

    tmp = Path(tempfile.mkdtemp(prefix="bench-ros-"))
    rig = Rig(tmp, params={"joint_state_rate": 100.0, "speed": 400.0}).start()
    watch = MotionWatch(rig.sim)
    # the driver alone on a sim of its own (a WSG takes motion commands from one connection at a time)
    bare = SimThread(udp_port=None).start()
    bare_watch = MotionWatch(bare)
    try:
        rig.call("wait")
        rig.call("trigger", name="homing")
        node_lat: list[float] = []
        driver_lat: list[float] = []
        with Gripper(bare.url) as g:
            g.home()
            for i in range(args.goals):
                width = 40.0 if i % 2 else 80.0
                # through the node: a GripperCommand goal from the client process
                watch.arm()
                out: dict[str, Any] = rig.call("goal", position=width / 1000)
                assert out["succeeded"], out
                node_lat.append(watch.wait_start() - out["t0"])
                # the driver alone: the same move from this process
                bare_watch.arm()
                t0 = time.monotonic()
                m = g.move(width, 400.0, wait=False)
                driver_lat.append(bare_watch.wait_start() - t0)
                m.wait()
            js = rig.call("joint_states", duration=args.seconds)
            with g.subscribe("width", period=0.01) as stream:
                time.sleep(args.seconds)
                samples = stream.drain()
        node_js = intervals([t for t in js["times"] if t > 0.2])
        drv = intervals([s.time for s in samples][20:])
        load = os.getloadavg()
        print(f"machine: {os.cpu_count()} cores, load average {load[0]:.2f} {load[1]:.2f} {load[2]:.2f}")
        print(f"goal-to-motion latency over {args.goals} goals (21h move, 400 mm/s)")
        print(f"  driver alone (Gripper.move)      {spread(driver_lat)}")
        print(f"  ROS node (GripperCommand goal)   {spread(node_lat)}")
        added = statistics.median(node_lat) - statistics.median(driver_lat)
        print(f"  added by ROS (median)            {added * 1e3:6.2f} ms")
        print(f"joint states over {args.seconds:g} s at a 10 ms stream period")
        for name, r in (("driver alone (43h stream)", drv), ("ROS node (joint_states)", node_js)):
            print(f"  {name:32s} {r['rate']:6.1f}/s  interval mean {r['mean'] * 1e3:5.2f} ms  stdev "
                  f"{r['stdev'] * 1e3:5.2f} ms  p99-p50 {(r['p99'] - r['p50']) * 1e3:5.2f} ms")
    finally:
        watch.close()
        bare_watch.close()
        rig.close()
        bare.stop()


if __name__ == "__main__":
    main()
