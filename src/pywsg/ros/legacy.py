"""wsg50-ros-pkg's interface, for people moving from that driver: its services (move, grasp, release,
homing, stop, ack, move_incrementally, set_acceleration, set_force), its ``status`` and ``moving``
topics and its ``goal_position`` subscription, with its ``wsg_50_common`` types, in the namespace
the ``legacy_namespace`` parameter names (default ``wsg_50_driver``: where that driver's node put
them). Units as that driver's: mm and mm/s. The services answer ``error`` = the gripper's status
code (0 = E_SUCCESS), 255 for a width outside the stroke, as that driver did."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from std_msgs.msg import Bool
from std_srvs.srv import Empty
from wsg_50_common.msg import Cmd, Status
from wsg_50_common.srv import Conf, Incr, Move

from ..client import Gripper
from ..errors import WsgError
from ..protocol import GripperState
from ..protocol import Status as WireStatus
from . import convert
from .host import NodeHost

#: the ROS 1 driver's answer to a width outside [0, stroke]
OUT_OF_RANGE = 255


class LegacyInterface:
    """The wsg50-ros-pkg services and topics of one node (created at configure, destroyed at cleanup)."""

    def __init__(self, node: NodeHost, namespace: str) -> None:
        self.node = node
        ns = namespace.strip("/")
        grp = node.group
        self._entities: list[Any] = [
            node.create_service(Move, f"{ns}/move", self._move, callback_group=grp),
            node.create_service(Move, f"{ns}/grasp", self._grasp, callback_group=grp),
            node.create_service(Move, f"{ns}/release", self._release, callback_group=grp),
            node.create_service(Empty, f"{ns}/homing", self._homing, callback_group=grp),
            node.create_service(Empty, f"{ns}/stop", self._stop, callback_group=grp),
            node.create_service(Empty, f"{ns}/ack", self._ack, callback_group=grp),
            node.create_service(Incr, f"{ns}/move_incrementally", self._incr, callback_group=grp),
            node.create_service(Conf, f"{ns}/set_acceleration", self._set_acc, callback_group=grp),
            node.create_service(Conf, f"{ns}/set_force", self._set_force, callback_group=grp),
            node.create_subscription(Cmd, f"{ns}/goal_position", self._goal_position, 5, callback_group=grp),
        ]
        self.status_pub = node.create_publisher(Status, f"{ns}/status", 10)
        self.moving_pub = node.create_publisher(Bool, f"{ns}/moving", 10)
        self._moving: bool | None = None
        self._entities += [self.status_pub, self.moving_pub]

    def destroy(self) -> None:
        for e in self._entities:
            self.node.destroy_entity(e)
        self._entities.clear()

    def publish(self) -> None:
        """The status message (and ``moving`` when it changes) from the live values; called with each
        joint state."""
        live = self.node.live
        msg = Status()
        msg.status = convert.state_name(live.gripper_state)
        msg.width = live.width
        msg.speed = live.speed
        msg.acc = float(self.node.acceleration)
        msg.force = live.force
        self.status_pub.publish(msg)
        moving = live.gripper_state in (GripperState.GRIPPING, GripperState.RELEASING, GripperState.POSITIONING)
        if moving != self._moving:
            self._moving = moving
            self.moving_pub.publish(Bool(data=moving))

    # -- services -----------------------------------------------------------------------------
    def _call(self, fn: Callable[[Gripper], object]) -> int:
        """Run a driver call; the gripper's status code of its failure, or 0."""
        g = self.node.gripper
        if g is None or not self.node.ready():
            return int(WireStatus.E_NOT_AVAILABLE)
        try:
            fn(g)
        except WsgError as exc:
            self.node.note_error(exc)
            return int(exc.status)
        return 0

    def _in_stroke(self, width: float) -> bool:
        return 0.0 <= width <= self.node.stroke

    def _motion(self, name: str, request: Any, response: Any) -> Any:
        if not self._in_stroke(request.width):
            response.error = OUT_OF_RANGE
            return response
        response.error = self._call(lambda g: getattr(g, name)(request.width, request.speed))
        return response

    def _move(self, request: Any, response: Any) -> Any:
        return self._motion("move", request, response)

    def _grasp(self, request: Any, response: Any) -> Any:
        return self._motion("grip", request, response)

    def _release(self, request: Any, response: Any) -> Any:
        return self._motion("release", request, response)

    def _homing(self, _request: Any, response: Any) -> Any:
        self._call(lambda g: g.home())
        return response

    def _stop(self, _request: Any, response: Any) -> Any:
        self._call(lambda g: g.stop())
        return response

    def _ack(self, _request: Any, response: Any) -> Any:
        self._call(lambda g: g.acknowledge())
        return response

    def _incr(self, request: Any, response: Any) -> Any:
        step = request.increment if request.direction == "open" else -request.increment
        if request.direction not in ("open", "close"):
            response.error = int(WireStatus.E_INVALID_PARAMETER)
            return response
        # relative to where the fingers are (21h relative; the gripper keeps the target inside its stroke)
        response.error = self._call(lambda g: g.move(step, self.node.settings.speed, relative=True))
        return response

    def _set_acc(self, request: Any, response: Any) -> Any:
        response.error = self._call(lambda g: g.set_acceleration(request.val))
        if response.error == 0:
            self.node.acceleration = request.val
        return response

    def _set_force(self, request: Any, response: Any) -> Any:
        response.error = self._call(lambda g: g.set_force_limit(request.val))
        return response

    def _goal_position(self, msg: Any) -> None:
        """A position command on the topic (the ROS 1 driver's auto_update and script modes): move there."""
        if not self._in_stroke(msg.pos):
            self.node.get_logger().error(f"goal_position {msg.pos} mm: outside the stroke")
            return
        g = self.node.gripper
        if g is None or not self.node.ready():
            return
        try:
            g.stop()
            g.move(msg.pos, msg.speed if msg.speed > 0 else self.node.settings.speed, wait=False)
        except WsgError as exc:
            self.node.note_error(exc)
