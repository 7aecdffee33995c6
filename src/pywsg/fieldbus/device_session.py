"""The fieldbus controller's own device session: what every part of the controller shares.

The controller drives the virtual gripper through a device session of its own ("fieldbus") with
ordinary request frames, so every rule of the binary protocol holds for the bus too (see
:mod:`pywsg.fieldbus.controller`). Here: sending those frames in order and keeping STATUS CODE
(002 §3.2: the last command's result, E_CMD_PENDING while it runs), the final replies that arrive
later, the system limits the parameters are checked against (53h), raising FAST STOP (002 §4.6) and
the log of what the controller did.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Protocol

from ..protocol import CATALOG, Command, Frame, GripperState, Status, SystemFlag
from .image import CmdFlag, OutputImage

if TYPE_CHECKING:
    from .bus import BusAdapter

log = logging.getLogger("pywsg.fieldbus.controller")

GS = GripperState
#: Final status of a motion command → the command that set it (for the ERROR rule).
_MOTION_IDS = {int(Command.HOMING): CmdFlag.HOMING, int(Command.PREPOSITION): CmdFlag.MOVE,
               int(Command.GRIP_PART): CmdFlag.GRIP, int(Command.RELEASE_PART): CmdFlag.RELEASE}


class FieldbusDevice(Protocol):
    """What the controller needs from :class:`pywsg.device.VirtualGripper`."""

    def open_session(self, kind: str, peer: str = ..., deliver: Callable[[Frame], None] | None = ...) -> Any: ...

    def close_session(self, session: Any) -> None: ...

    def handle_frame(self, session: Any, frame: Frame) -> list[Frame]: ...

    def snapshot(self) -> Any: ...

    def jog(self, direction: int, speed: float, force: float) -> Status | int: ...

    def reset_gripper_state(self) -> None: ...


@dataclass(frozen=True)
class Limits:
    """System limits used to check bus parameters (53h Get System Limits): mm, mm/s, N."""

    stroke: float
    min_speed: float
    max_speed: float
    min_force: float
    nom_force: float
    ovr_force: float


@dataclass(frozen=True)
class Event:
    """One thing the controller did, for logs and monitors."""

    time: float
    text: str


class DeviceSession:
    """The state of one fieldbus controller and its requests to the gripper (a base of
    :class:`~pywsg.fieldbus.controller.FieldbusController`)."""

    gripper: FieldbusDevice
    model: str
    force_scale: float
    output_image: OutputImage
    status: int
    events: list[Event]
    _pending: int | None   # command ID whose final reply sets STATUS
    _jog_dir: int
    _jog_done: bool
    # The fieldbus gripper state shown instead of the device's (ERROR after a failed motion, IDLE
    # after FAST STOP) until the next accepted command; _failed is a final error not yet resolved.
    _shown: GripperState | None
    _failed: tuple[CmdFlag, int] | None
    _listeners: list[Callable[[Event], None]]
    _buses: list[BusAdapter]
    session: Any
    limits: Limits

    def _run(self, frames: list[tuple[Command, dict[str, Any]]]) -> bool:
        """Send request frames in order; STATUS = the last one's immediate status. False on error."""
        self._pending = None
        for cmd, values in frames:
            frame = Frame(int(cmd), CATALOG[cmd].encode_request(values))
            replies = self.gripper.handle_frame(self.session, frame)
            status = int(Status.E_SUCCESS)
            for reply in replies:
                if reply.command_id == int(cmd):
                    status = int(reply.status)
            if status == Status.E_CMD_PENDING:
                self._pending = int(cmd)
            self._set_status(status)
            if status not in (Status.E_SUCCESS, Status.E_CMD_PENDING):
                self._emit(f"{CATALOG[cmd].name} -> {Status.describe(status)}")
                return False
        return True

    def _deliver(self, frame: Frame) -> None:
        """Deferred frames of the fieldbus session: final replies of motions."""
        if self._pending is not None and frame.command_id == self._pending:
            status = int(frame.status)
            if status != Status.E_CMD_PENDING:
                self._pending = None
                self._set_status(status)
                self._emit(f"{CATALOG[frame.command_id].name} finished: {Status.describe(status)}")
                if status != Status.E_SUCCESS and frame.command_id in _MOTION_IDS:
                    # resolved on the next read, when the device has settled its own state
                    self._failed = (_MOTION_IDS[frame.command_id], status)

    def _set_status(self, status: Status | int) -> None:
        self.status = int(status)

    def _emit(self, text: str) -> None:
        now = float(getattr(self.gripper.snapshot(), "time", 0.0))
        event = Event(now, text)
        self.events.append(event)
        del self.events[:-200]
        log.debug("fieldbus: %s", text)
        for fn in list(self._listeners):
            fn(event)

    def _max_force(self) -> float:
        snap = self.gripper.snapshot()
        if snap.flags & SystemFlag.SF_OVERDRIVE_MODE:
            return self.limits.ovr_force
        return self.limits.nom_force

    def _current_force_limit(self) -> float:
        value = getattr(self.gripper.snapshot(), "force_limit", None)
        return float(value) if value else self.limits.nom_force

    def _read_limits(self) -> Limits:
        frame = Frame(int(Command.GET_SYSTEM_LIMITS), b"")
        for reply in self.gripper.handle_frame(self.session, frame):
            if reply.command_id == Command.GET_SYSTEM_LIMITS and reply.status == Status.E_SUCCESS:
                _, v = CATALOG[Command.GET_SYSTEM_LIMITS].decode_reply(reply.payload)
                return Limits(float(v["stroke"]), float(v["min_speed"]), float(v["max_speed"]),
                              float(v["min_force"]), float(v["nom_force"]), float(v["ovr_force"]))
        raise RuntimeError("the gripper did not answer 53h Get System Limits")

    def _raise_fast_stop(self, reason: str, status: Status) -> None:
        self._emit(f"FAST STOP: {reason}")
        self._stop_jog()
        self._run([(Command.FAST_STOP, {})])
        self._shown, self._failed = GS.IDLE, None   # 002 §4.6 / 003 §5.6
        self._set_status(status)

    def _stop_jog(self) -> None:
        if self._jog_dir:
            self._jog_dir = 0
            self.gripper.jog(0, 0.0, 0.0)

    def add_listener(self, fn: Callable[[Event], None]) -> None:
        """Call ``fn(event)`` for every command the controller issues."""
        self._listeners.append(fn)
