"""control_msgs/action/GripperCommand on the driver: ``position`` is the gap between the fingers in
metres, ``max_effort`` the grip force in N.

- ``max_effort`` > 0 and a goal narrower than the opening: grip (25h Grip Part with that force,
  000 §3.2.6; the position is the part's nominal width);
- a goal wider than the opening while a part is held: release (26h);
- otherwise: pre-position (21h, stopping on a block), a position goal without force control.

The result comes from the gripper state at the end (:func:`~pywsg.ros.convert.outcome`): HOLDING is
stalled at the part, NO_PART is not reached; a blocked pre-position is stalled and aborted. A cancel
stops the fingers (22h Stop)."""

from __future__ import annotations

import threading
from typing import Any

from control_msgs.action import GripperCommand
from rclpy.action import ActionServer, CancelResponse, GoalResponse
from rclpy.action.server import ServerGoalHandle

from ..errors import AbortedError, AxisBlockedError, WsgError
from ..protocol import GripperState
from . import convert
from .host import NodeHost


class GripperCommandServer:
    """The action server of one node; one goal at a time (a new goal preempts the running one)."""

    def __init__(self, node: NodeHost, name: str = "~/gripper_cmd") -> None:
        self.node = node
        self._lock = threading.Lock()
        self._current: ServerGoalHandle | None = None
        self._finished = threading.Event()  # set while no goal's motion runs
        self._finished.set()
        self.server = ActionServer(node, GripperCommand, name, execute_callback=self._execute,
                                   goal_callback=self._on_goal, cancel_callback=self._on_cancel,
                                   callback_group=node.group)

    def destroy(self) -> None:
        self.server.destroy()

    def halt(self, timeout: float) -> None:
        """Stop a running goal's fingers (22h) and wait up to ``timeout`` s for the goal to end (aborted):
        before the node releases the gripper."""
        with self._lock:
            self._current = None
        self._finished.wait(timeout)

    # -- callbacks ----------------------------------------------------------------------------
    def _on_goal(self, _request: Any) -> GoalResponse:
        return GoalResponse.ACCEPT if self.node.ready() else GoalResponse.REJECT

    def _on_cancel(self, _goal: ServerGoalHandle) -> CancelResponse:
        return CancelResponse.ACCEPT

    def _execute(self, goal: ServerGoalHandle) -> Any:
        with self._lock:
            previous, self._current = self._current, goal
        if previous is not None:
            self.node.get_logger().info("a new GripperCommand goal preempts the running one")
            # the previous goal's loop sees it is no longer current, stops the fingers and ends
            self._finished.wait(self.node.settings.timeout * 5)
        with self._lock:
            if self._current is not goal:  # preempted in turn before it started
                goal.abort()
                return self._result()
            self._finished.clear()
        try:
            return self._run(goal)
        finally:
            with self._lock:
                if self._current is goal:
                    self._current = None
                self._finished.set()

    # -- one goal -----------------------------------------------------------------------------
    def _run(self, goal: ServerGoalHandle) -> Any:
        node, s = self.node, self.node.settings
        g = node.gripper
        if g is None or not node.ready():
            goal.abort()
            return self._result()
        command = goal.request.command
        width = convert.to_mm(command.position)
        now = node.live.width
        tolerance = convert.to_mm(s.goal_tolerance)
        try:
            if command.max_effort > 0 and width < now - tolerance:
                motion = g.grip(width, s.speed, force=command.max_effort, wait=False)
            elif node.live.gripper_state == GripperState.HOLDING and width > now + tolerance:
                motion = g.release(width, s.speed, wait=False)
            else:
                motion = g.move(width, s.speed, stop_on_block=True, wait=False)
        except WsgError as exc:
            node.note_error(exc)
            goal.abort()
            return self._result()
        period = 1.0 / s.feedback_rate
        canceled = False
        while not motion.done():
            if not canceled and (goal.is_cancel_requested or self._current is not goal):
                canceled = True
                try:
                    g.stop()
                except WsgError as exc:
                    node.note_error(exc)
            node.live.wait_width_after(node.live.width_time, period)
            if goal.is_active:
                goal.publish_feedback(self._feedback())
        error: WsgError | None = None
        try:
            motion.wait(0)
        except WsgError as exc:
            error = exc
            if not isinstance(exc, AbortedError | AxisBlockedError):
                node.note_error(exc)
        state = self._final_state()
        result = self._result()
        if canceled or isinstance(error, AbortedError):
            if goal.is_cancel_requested:
                goal.canceled()
            else:
                goal.abort()
            return result
        out = convert.outcome(state) if state is not None else convert.Outcome(False, False, False)
        if error is None and state is None:  # no gripper state came: the motion's own word
            out = convert.Outcome(True, True, False)
        result.reached_goal, result.stalled = out.reached_goal, out.stalled
        if isinstance(error, AxisBlockedError):  # a position goal ran into something
            result.reached_goal, result.stalled = False, True
        if out.succeeded and error is None:
            goal.succeed()
        else:
            goal.abort()
        return result

    def _final_state(self) -> GripperState | int | None:
        """The gripper state once the motion is over, read with the opening and force into the live values
        (read, not streamed: a stream sample may come after the motion's final reply)."""
        node = self.node
        g = node.gripper
        try:
            if g is None:
                return None
            st = g.state()
        except WsgError:
            return node.live.gripper_state
        node.live.width, node.live.force, node.live.gripper_state = st.width, st.force, st.gripper_state
        return st.gripper_state

    def _feedback(self) -> Any:
        live = self.node.live
        fb = GripperCommand.Feedback()
        fb.position = convert.to_m(live.width)
        fb.effort = live.force
        fb.stalled = live.gripper_state == GripperState.HOLDING
        fb.reached_goal = False
        return fb

    def _result(self) -> Any:
        live = self.node.live
        r = GripperCommand.Result()
        r.position = convert.to_m(live.width)
        r.effort = live.force
        return r
