"""A second rclpy process: the ROS client of pywsg's ROS tests (run by tests/ros/rig.py with .venv-ros's Python).

Reads one JSON request per line on stdin, answers one JSON line on stdout: {"ok": true, ...} or
{"ok": false, "error": "..."}. It keeps every joint_states, /diagnostics and legacy status message it
receives, with its arrival time, so a test can ask what arrived during a goal."""

from __future__ import annotations

import json
import sys
import threading
import time
import traceback
from typing import Any

import rclpy
from action_msgs.msg import GoalStatus
from control_msgs.action import GripperCommand
from diagnostic_msgs.msg import DiagnosticArray
from lifecycle_msgs.msg import Transition
from lifecycle_msgs.srv import ChangeState, GetState
from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
from rcl_interfaces.srv import SetParameters
from rclpy.action import ActionClient
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.executors import MultiThreadedExecutor
from rclpy.node import Node
from sensor_msgs.msg import JointState
from std_srvs.srv import Empty, Trigger
from wsg_50_common.msg import Status
from wsg_50_common.srv import Conf, Incr, Move

TRANSITIONS = {"configure": Transition.TRANSITION_CONFIGURE, "activate": Transition.TRANSITION_ACTIVATE,
               "deactivate": Transition.TRANSITION_DEACTIVATE, "cleanup": Transition.TRANSITION_CLEANUP}
LEGACY_TYPES = {"move": Move, "grasp": Move, "release": Move, "homing": Empty, "stop": Empty, "ack": Empty,
                "set_acceleration": Conf, "set_force": Conf, "move_incrementally": Incr}


def wait_future(future: Any, timeout: float) -> Any:
    end = time.monotonic() + timeout
    while not future.done():
        if time.monotonic() > end:
            raise TimeoutError(f"no answer within {timeout:g} s")
        time.sleep(0.002)
    return future.result()


class Client(Node):
    def __init__(self, target: str, legacy: str) -> None:
        super().__init__("wsg_test_client")
        grp = ReentrantCallbackGroup()
        self.target, self.legacy_ns = target, legacy
        self.lock = threading.Lock()
        self.joint_states: list[tuple[float, list[float], list[float], list[str]]] = []
        self.diagnostics: list[tuple[float, dict[str, Any]]] = []
        self.statuses: list[tuple[float, dict[str, Any]]] = []
        self.create_subscription(JointState, "/joint_states", self._on_js, 100, callback_group=grp)
        self.create_subscription(DiagnosticArray, "/diagnostics", self._on_diag, 10, callback_group=grp)
        self.create_subscription(Status, f"/{legacy}/status", self._on_status, 10, callback_group=grp)
        self.action = ActionClient(self, GripperCommand, f"{target}/gripper_cmd", callback_group=grp)
        self.triggers = {n: self.create_client(Trigger, f"{target}/{n}", callback_group=grp)
                         for n in ("homing", "stop", "fast_stop", "acknowledge")}
        self.legacy = {n: self.create_client(t, f"/{legacy}/{n}", callback_group=grp) for n, t in LEGACY_TYPES.items()}
        self.change_state = self.create_client(ChangeState, f"{target}/change_state", callback_group=grp)
        self.get_state = self.create_client(GetState, f"{target}/get_state", callback_group=grp)
        self.set_params = self.create_client(SetParameters, f"{target}/set_parameters", callback_group=grp)

    # -- recorders ----------------------------------------------------------------------------
    def _on_js(self, msg: JointState) -> None:
        with self.lock:
            self.joint_states.append((time.monotonic(), list(msg.position), list(msg.effort), list(msg.name)))

    def _on_diag(self, msg: DiagnosticArray) -> None:
        for st in msg.status:
            d = {"level": st.level[0] if isinstance(st.level, bytes) else int(st.level), "name": st.name,
                 "message": st.message, "hardware_id": st.hardware_id, "values": {kv.key: kv.value for kv in st.values}}
            with self.lock:
                self.diagnostics.append((time.monotonic(), d))

    def _on_status(self, msg: Status) -> None:
        d = {f: getattr(msg, f) for f in ("status", "width", "speed", "acc", "force", "force_finger0", "force_finger1")}
        with self.lock:
            self.statuses.append((time.monotonic(), d))

    # -- requests -----------------------------------------------------------------------------
    def op_wait(self, timeout: float = 30.0, configured: bool = True, active: bool = False) -> dict[str, Any]:
        """Wait for the node's services (``configured``: also those configure makes) and its action;
        ``active``: until the node is active too."""
        end = time.monotonic() + timeout
        clients = [self.change_state, self.get_state, self.set_params]
        if configured:
            clients += [*self.triggers.values(), *self.legacy.values()]
        for c in clients:
            if not c.wait_for_service(timeout_sec=max(0.1, end - time.monotonic())):
                raise TimeoutError(f"service {c.srv_name} not found")
        if configured and not self.action.wait_for_server(timeout_sec=max(0.1, end - time.monotonic())):
            raise TimeoutError("action server not found")
        while active and self.op_state()["state"] != "active":
            if time.monotonic() > end:
                raise TimeoutError("the node did not become active")
            time.sleep(0.05)
        return {}

    def op_goal(self, position: float, max_effort: float = 0.0, cancel_after: float | None = None,
                deactivate_after: float | None = None, timeout: float = 30.0) -> dict[str, Any]:
        goal = GripperCommand.Goal()
        goal.command.position = float(position)
        goal.command.max_effort = float(max_effort)
        feedback: list[dict[str, Any]] = []
        t0 = time.monotonic()
        handle = wait_future(self.action.send_goal_async(
            goal, feedback_callback=lambda m: feedback.append(
                {"t": time.monotonic() - t0, "position": m.feedback.position, "effort": m.feedback.effort})), 10)
        if not handle.accepted:
            return {"accepted": False}
        result_future = handle.get_result_async()
        if cancel_after is not None:
            time.sleep(cancel_after)
            wait_future(handle.cancel_goal_async(), 10)
        if deactivate_after is not None:
            time.sleep(deactivate_after)
            self.op_transition("deactivate")
        res = wait_future(result_future, timeout)
        t1 = time.monotonic()
        with self.lock:
            during = [js for js in self.joint_states if t0 <= js[0] <= t1]
        r = res.result
        return {"accepted": True, "status": res.status, "succeeded": res.status == GoalStatus.STATUS_SUCCEEDED,
                "canceled": res.status == GoalStatus.STATUS_CANCELED,
                "aborted": res.status == GoalStatus.STATUS_ABORTED, "duration": t1 - t0, "t0": t0,
                "result": {"position": r.position, "effort": r.effort, "stalled": r.stalled,
                           "reached_goal": r.reached_goal},
                "feedback": feedback, "joint_states": [[js[0] - t0, js[1]] for js in during]}

    def op_trigger(self, name: str) -> dict[str, Any]:
        res = wait_future(self.triggers[name].call_async(Trigger.Request()), 30)
        return {"success": res.success, "message": res.message}

    def op_legacy(self, name: str, **fields: Any) -> dict[str, Any]:
        srv = LEGACY_TYPES[name]
        req = srv.Request()
        for k, v in fields.items():
            setattr(req, k, v)
        res = wait_future(self.legacy[name].call_async(req), 30)
        return {"error": getattr(res, "error", None)}

    def op_transition(self, name: str) -> dict[str, Any]:
        req = ChangeState.Request()
        req.transition.id = TRANSITIONS[name]
        res = wait_future(self.change_state.call_async(req), 30)
        return {"success": res.success, **self.op_state()}

    def op_state(self) -> dict[str, Any]:
        res = wait_future(self.get_state.call_async(GetState.Request()), 10)
        return {"state": res.current_state.label}

    def op_set_param(self, name: str, value: Any) -> dict[str, Any]:
        pv = ParameterValue()
        if isinstance(value, bool):
            pv.type, pv.bool_value = ParameterType.PARAMETER_BOOL, value
        elif isinstance(value, float):
            pv.type, pv.double_value = ParameterType.PARAMETER_DOUBLE, value
        else:
            pv.type, pv.string_value = ParameterType.PARAMETER_STRING, str(value)
        req = SetParameters.Request(parameters=[Parameter(name=name, value=pv)])
        res = wait_future(self.set_params.call_async(req), 10)
        return {"successful": res.results[0].successful, "reason": res.results[0].reason}

    def op_diag(self, contains: str = "", key: str = "system_flags", absent: str = "", level: int | None = None,
                timeout: float = 15.0) -> dict[str, Any]:
        """Wait for a diagnostic status whose ``key`` value contains ``contains`` (and not ``absent``)
        and whose level is ``level`` when given; the newest one arrived after this call started."""
        t0, end = time.monotonic(), time.monotonic() + timeout
        while time.monotonic() < end:
            with self.lock:
                found = [d for t, d in self.diagnostics if t >= t0]
            for d in reversed(found):
                v = d["values"].get(key, "")
                if contains in v and (not absent or absent not in v) and (level is None or d["level"] == level):
                    return {"status": d}
            time.sleep(0.05)
        with self.lock:
            last = self.diagnostics[-1][1] if self.diagnostics else None
        raise TimeoutError(f"no matching diagnostics within {timeout} s; last: {last}")

    def op_joint_states(self, duration: float) -> dict[str, Any]:
        t0 = time.monotonic()
        time.sleep(duration)
        with self.lock:
            got = [js for js in self.joint_states if js[0] >= t0]
        return {"t0": t0, "times": [js[0] - t0 for js in got], "positions": [js[1] for js in got],
                "efforts": [js[2] for js in got], "names": got[-1][3] if got else []}

    def op_status(self, timeout: float = 10.0) -> dict[str, Any]:
        t0, end = time.monotonic(), time.monotonic() + timeout
        while time.monotonic() < end:
            with self.lock:
                found = [d for t, d in self.statuses if t >= t0]
            if found:
                return {"status": found[-1]}
            time.sleep(0.02)
        raise TimeoutError("no wsg_50_common/Status message")


def main() -> None:
    target, legacy = sys.argv[1], sys.argv[2]
    rclpy.init()
    node = Client(target, legacy)
    executor = MultiThreadedExecutor(num_threads=4)
    executor.add_node(node)
    spinner = threading.Thread(target=executor.spin, daemon=True)
    spinner.start()
    try:
        print(json.dumps({"ok": True, "ready": True}), flush=True)
        for line in sys.stdin:
            req = json.loads(line)
            op = req.pop("op")
            if op == "quit":
                break
            try:
                out = {"ok": True, **getattr(node, f"op_{op}")(**req)}
            except Exception as exc:
                out = {"ok": False, "error": f"{type(exc).__name__}: {exc}", "trace": traceback.format_exc()}
            print(json.dumps(out), flush=True)
    finally:
        # the executor stopped and its thread joined before rclpy shuts down (rclpy aborts otherwise)
        executor.shutdown()
        spinner.join(5)
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == "__main__":
    main()
