"""The managed (lifecycle) node: ``configure`` connects, ``activate`` starts the streams and the
interfaces, ``deactivate`` releases the gripper with its disconnect announcement (07h, 000 §3.1.2),
``cleanup`` removes the interfaces.

Interfaces (names relative to the node; docs/ros.md has the table):

- ``~/gripper_cmd``: control_msgs/action/GripperCommand (:mod:`.gripper_action`);
- ``joint_states``: sensor_msgs/JointState of the two fingers, from the auto-update streams of the
  width, speed and force, which keep running while goals run;
- ``~/homing``, ``~/stop``, ``~/fast_stop``, ``~/acknowledge``: std_srvs/Trigger;
- ``/diagnostics``: diagnostic_msgs/DiagnosticArray (system flags, temperature, last error);
- wsg50-ros-pkg's services and topics under ``legacy_namespace`` (:mod:`.legacy`).
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rcl_interfaces.msg import SetParametersResult
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.lifecycle import LifecycleNode, TransitionCallbackReturn
from rclpy.parameter import Parameter
from rclpy.publisher import Publisher
from rclpy.service import Service
from rclpy.subscription import Subscription
from rclpy.timer import Timer
from sensor_msgs.msg import JointState
from std_srvs.srv import Trigger

from ..client import Gripper, ReconnectPolicy, Sample, Stream
from ..errors import WsgError
from ..protocol import SystemFlag
from . import convert, params
from .gripper_action import GripperCommandServer
from .live import Live

#: reconnect for as long as the node lives (each try at most 2 s apart)
FOREVER = ReconnectPolicy(attempts=1 << 30, delay=0.2, max_delay=2.0)

SUCCESS = TransitionCallbackReturn.SUCCESS
FAILURE = TransitionCallbackReturn.FAILURE


class WsgNode(LifecycleNode):  # type: ignore[misc]  # rclpy is untyped here
    """A WSG gripper as a ROS 2 lifecycle node, driving any pywsg URL (real or ``wsg sim``)."""

    def __init__(self, node_name: str = "wsg_gripper", **kwargs: Any) -> None:
        super().__init__(node_name, **kwargs)
        self.settings = params.declare(self)
        self.group = ReentrantCallbackGroup()
        self.gripper: Gripper | None = None
        self.live = Live()
        self.stroke = 110.0  # mm, from 53h at configure
        self.acceleration = 0.0  # mm/s², from 31h at configure
        self.hardware_id = ""
        self.last_error = ""
        self._active = False
        self._streams: list[Stream] = []
        self._ros: list[Any] = []  # what configure made and cleanup destroys
        self._action: Any = None
        self._legacy: Any = None
        self._joint_pub: Any = None
        self._diag_pub: Any = None
        self.add_on_set_parameters_callback(self._on_set_parameters)

    # -- lifecycle ----------------------------------------------------------------------------
    def on_configure(self, state: Any) -> TransitionCallbackReturn:
        self.settings = s = params.read(self)
        if len(s.joint_names) != 2 or len(s.joint_signs) != 2:
            self.get_logger().error("joint_names, joint_signs: give two, for the fingers (left, right)")
            return FAILURE
        try:
            self._connect()
        except (WsgError, ValueError) as exc:  # ValueError: a URL pywsg cannot read
            self.get_logger().error(f"cannot connect to {s.url}: {exc}")
            self.note_error(exc)
            self._release()
            return FAILURE
        self._make_interfaces()
        self.get_logger().info(f"configured: {s.url} ({self.hardware_id})")
        return SUCCESS

    def on_activate(self, state: Any) -> TransitionCallbackReturn:
        try:
            if self.gripper is None:  # deactivate released it: connect again
                self._connect()
            self._subscribe()
        except WsgError as exc:
            self.get_logger().error(f"cannot activate: {exc}")
            self.note_error(exc)
            self._release()
            return FAILURE
        self._active = True
        return SUCCESS

    def on_deactivate(self, state: Any) -> TransitionCallbackReturn:
        self._active = False
        self._halt()
        self._release()
        return SUCCESS

    def on_cleanup(self, state: Any) -> TransitionCallbackReturn:
        self._active = False
        self._halt()
        self._release()
        self._destroy_interfaces()
        return SUCCESS

    def on_shutdown(self, state: Any) -> TransitionCallbackReturn:
        return self.on_cleanup(state)

    def on_error(self, state: Any) -> TransitionCallbackReturn:
        self._active = False
        self._release()
        return SUCCESS

    def _halt(self) -> None:
        """A running goal stops its fingers and ends before the gripper is released."""
        if self._action is not None:
            self._action.halt(self.settings.timeout * 5)

    def ready(self) -> bool:
        """Active with a gripper: goals and service calls are taken."""
        return self._active and self.gripper is not None

    # -- the gripper --------------------------------------------------------------------------
    def _connect(self) -> None:
        s = self.settings
        g = Gripper(s.url, timeout=s.timeout, connect=False, reconnect=FOREVER if s.reconnect else False,
                    on_reconnect=self._on_reconnect, on_connection_lost=self._on_connection_lost)
        g.connect()
        self.gripper = g
        info = g.info()
        self.hardware_id = f"WSG type {int(info.type)}, serial number {info.serial_number}"
        self.stroke = g.limits().stroke
        if s.acceleration > 0:
            g.set_acceleration(s.acceleration)
        if s.force_limit > 0:
            g.set_force_limit(s.force_limit)
        self.acceleration = g.acceleration()
        self.live.flags = g.system_state()
        self.live.gripper_state = g.gripper_state()
        self.live.width = g.width()

    def _subscribe(self) -> None:
        g = self.gripper
        assert g is not None
        period = max(0.01, 1.0 / self.settings.joint_state_rate)
        take = self.live.take
        self._streams = [
            g.subscribe("gripper_state", 0.01, change_only=True, callback=take, maxlen=1),
            g.subscribe("system_state", 0.01, change_only=True, callback=take, maxlen=1),
            g.subscribe("speed", period, callback=take, maxlen=1),
            g.subscribe("force", period, callback=take, maxlen=1),
            g.subscribe("width", period, callback=self._on_width, maxlen=1),  # last: publishes what came
        ]

    def _release(self) -> None:
        """Close the streams and the connection with the disconnect announcement (no FAST STOP)."""
        g, self.gripper = self.gripper, None
        streams, self._streams = self._streams, []
        if g is None:
            return
        for st in streams:
            try:
                st.close()
            except WsgError:
                pass
        g.close()
        self.live.flags = None

    def _on_reconnect(self, flags: SystemFlag) -> None:
        self.live.flags = flags
        if flags & SystemFlag.SF_FAST_STOP and self.settings.acknowledge_after_reconnect:
            # on a thread of its own: this callback runs inside the driver's reconnection
            threading.Thread(target=self._acknowledge_after_reconnect, name="wsg-ros-ack", daemon=True).start()
        elif flags & SystemFlag.SF_FAST_STOP:
            self.get_logger().warning("reconnected into a FAST STOP: call ~/acknowledge once its cause is fixed "
                                      "(or set acknowledge_after_reconnect)")

    def _acknowledge_after_reconnect(self) -> None:
        g = self.gripper
        if g is None:
            return
        try:
            g.acknowledge()
            self.live.flags = g.system_state()
            self.get_logger().warning("reconnected into a FAST STOP: acknowledged (acknowledge_after_reconnect)")
        except WsgError as exc:
            self.note_error(exc)

    def _on_connection_lost(self, exc: BaseException | None) -> None:
        self.last_error = f"connection lost: {exc}" if exc else "connection lost"

    def note_error(self, exc: BaseException) -> None:
        """Remember ``exc`` as the last error (diagnostics) and log it."""
        self.last_error = str(exc)
        self.get_logger().warning(self.last_error)

    # -- interfaces ---------------------------------------------------------------------------
    def _make_interfaces(self) -> None:
        s, grp = self.settings, self.group
        self._joint_pub = self.create_publisher(JointState, "joint_states", 10)
        self._diag_pub = self.create_publisher(DiagnosticArray, "/diagnostics", 10)
        self._ros = [self._joint_pub, self._diag_pub]
        for name, fn in self._triggers().items():
            self._ros.append(self.create_service(Trigger, f"~/{name}", self._trigger(fn), callback_group=grp))
        self._ros.append(self.create_timer(1.0 / s.diagnostics_rate, self._publish_diagnostics, callback_group=grp))
        self._action = GripperCommandServer(self)
        if s.legacy_namespace.strip("/"):
            try:
                from .legacy import LegacyInterface
            except ImportError as exc:
                self.get_logger().warning(f"wsg50-ros-pkg interface not offered: {exc} (build wsg_50_common)")
            else:
                self._legacy = LegacyInterface(self, s.legacy_namespace)

    def _destroy_interfaces(self) -> None:
        if self._action is not None:
            self._action.destroy()
            self._action = None
        if self._legacy is not None:
            self._legacy.destroy()
            self._legacy = None
        for e in self._ros:
            self.destroy_entity(e)
        self._ros = []
        self._joint_pub = self._diag_pub = None

    def destroy_entity(self, entity: Any) -> None:
        """Destroy a publisher, subscription, service or timer this node made."""
        if isinstance(entity, Publisher):
            self.destroy_publisher(entity)
        elif isinstance(entity, Subscription):
            self.destroy_subscription(entity)
        elif isinstance(entity, Service):
            self.destroy_service(entity)
        elif isinstance(entity, Timer):
            self.destroy_timer(entity)

    @staticmethod
    def _triggers() -> dict[str, Callable[[Gripper], object]]:
        return {
            "homing": lambda g: g.home(),  # 20h
            "stop": lambda g: g.stop(),  # 22h
            "fast_stop": lambda g: g.fast_stop(),  # 23h
            "acknowledge": lambda g: g.acknowledge(),  # 24h
        }

    def _trigger(self, fn: Callable[[Gripper], object]) -> Callable[[Any, Any], Any]:
        def serve(_request: Any, response: Any) -> Any:
            g = self.gripper
            if g is None or not self.ready():
                response.success, response.message = False, "not active: configure and activate the node"
                return response
            try:
                fn(g)
            except WsgError as exc:
                self.note_error(exc)
                response.success, response.message = False, str(exc)
                return response
            response.success, response.message = True, "done"
            return response
        return serve

    # -- publishing ---------------------------------------------------------------------------
    def _on_width(self, sample: Sample) -> None:
        self.live.take(sample)
        pub = self._joint_pub
        if pub is None or not self._active:
            return
        live, s = self.live, self.settings
        msg = JointState()
        msg.header.stamp = self.get_clock().now().to_msg()
        msg.header.frame_id = s.frame_id
        msg.name = list(s.joint_names)
        signs = (s.joint_signs[0], s.joint_signs[1])
        msg.position = list(convert.finger_positions(live.width, signs))
        msg.velocity = list(convert.finger_velocities(live.speed, signs))
        msg.effort = [live.force, live.force]
        pub.publish(msg)
        legacy = self._legacy
        if legacy is not None:
            legacy.publish()

    def _publish_diagnostics(self) -> None:
        pub = self._diag_pub
        if pub is None:
            return
        g = self.gripper
        flags = self.live.flags if g is not None and g.connected else None
        temperature: float | None = None
        if flags is not None and g is not None:
            try:
                temperature = g.temperature()
            except WsgError as exc:
                self.note_error(exc)
        level, message = convert.diagnostic_level(flags)
        if not self._active and flags is None:
            message = "inactive: the gripper is released"
        st = DiagnosticStatus()
        st.level = bytes([level])
        st.name = f"{self.get_name()}: WSG gripper"
        st.message = message
        st.hardware_id = self.hardware_id
        values = {
            "url": self.settings.url,
            "system_flags": " ".join(convert.flag_names(flags)) if flags is not None else "",
            "system_flags_hex": f"0x{int(flags):08X}" if flags is not None else "",
            "gripper_state": convert.state_name(self.live.gripper_state),
            "width_mm": f"{self.live.width:.2f}",
            "force_n": f"{self.live.force:.1f}",
            "temperature_c": f"{temperature:.1f}" if temperature is not None else "",
            "last_error": self.last_error,
        }
        st.values = [KeyValue(key=k, value=v) for k, v in values.items()]
        arr = DiagnosticArray()
        arr.header.stamp = self.get_clock().now().to_msg()
        arr.status = [st]
        pub.publish(arr)

    # -- parameters ---------------------------------------------------------------------------
    def _on_set_parameters(self, changed: list[Parameter]) -> SetParametersResult:
        g = self.gripper
        for p in changed:
            if p.name not in params.DYNAMIC:
                continue
            if g is not None and p.name == "acceleration" and p.value > 0:
                try:
                    g.set_acceleration(p.value)
                    self.acceleration = g.acceleration()
                except WsgError as exc:
                    return SetParametersResult(successful=False, reason=str(exc))
            elif g is not None and p.name == "force_limit" and p.value > 0:
                try:
                    g.set_force_limit(p.value)
                except WsgError as exc:
                    return SetParametersResult(successful=False, reason=str(exc))
            setattr(self.settings, p.name, p.value)
        return SetParametersResult(successful=True)
