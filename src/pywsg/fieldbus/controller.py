"""The fieldbus controller: turns output-image updates into gripper commands (002 §3.1, §4).

Sans-IO. It drives the virtual gripper through its own device session ("fieldbus") with ordinary
request frames (20h Homing, 21h Pre-position, 22h Stop, 23h FAST STOP, 24h Ack, 25h Grip, 26h Release,
32h Set Force Limit), so every rule of the binary protocol holds for the bus too; final replies come
back through the session's ``deliver`` callback. Jog mode uses ``gripper.jog()``.

Rules (002 §3.1, §4 / 003 §5, and the decisions in docs/fieldbus.md and docs/fidelity.md):

- A command fires on a 0→1 edge of its CMDFLAGS bit; if several rise in one update the lowest bit
  wins. A rising FASTSTOP is never lost: it is executed even when a lower bit rises with it.
- JOG+ / JOG- are levels: 10 → positive, 01 → negative, 11 → stop, 00 after jogging → stop.
  SPEED 0 means the minimum speed; FORCELIMIT 0 keeps the current force limit (jog only).
- While FASTSTOP or STOP/ACK is held at 1, motion commands are not started (STATUS = E_ACCESS_DENIED).
- STOP/ACK stops a motion (22h), or acknowledges a FAST STOP (24h "ack", then 22h so the gripper
  state is IDLE) — only once FASTSTOP has been reset to 0, else STATUS = E_ACCESS_DENIED.
- A parameter beyond the system limits used by a motion command raises FAST STOP (STATUS =
  E_RANGE_ERROR); changing WIDTH/SPEED/FORCELIMIT while SF_MOVING (not jogging) raises FAST STOP
  (STATUS = E_CMD_ABORTED).
- STATUS CODE holds the last command's result: E_CMD_PENDING while it runs, then its final status.
- IF is copied to the gripper's script flags on every update; OF is read from them.

Gripper state (GSTATE) is the fieldbus manuals' own, computed here on top of the device's state,
so it holds whatever the binary protocol's 41h reports (decisions in docs/fidelity.md):

- Preconditions (002 §4.1 / 003 §5.1 "MOVE can only be issued if the gripper is idle"; the others
  decided by analogy, table :data:`STARTS_FROM`): a motion edge in another state is refused and the
  motion in progress is left alone; STATUS = E_ALREADY_RUNNING while a motion runs, else
  E_ACCESS_DENIED.
- "In case of an error, the gripper state is set to ERROR" (002 §4.1–4.3, 003 §5.1–5.3): a MOVE,
  GRIP, RELEASE or HOMING whose final status is an error shows ERROR with that status until the
  next accepted command (a GRIP that finds no part is NO_PART / E_CMD_FAILED, as §4.2 says).
  MOVE stops on a block (21h flag STOP_ON_BLOCK) instead of clamping on, so it ends.
- FAST STOP: "The gripper state is set to IDLE" (002 §4.6, 003 §5.6), from any source, while the
  FAST STOP lasts and until the next accepted command or a motion started elsewhere.

One controller, many buses: every bus adapter (:class:`~pywsg.fieldbus.bus.BusAdapter`) of the
gripper feeds this one controller and registers with :meth:`FieldbusController.attach_bus`; a bus
whose master is lost calls :meth:`FieldbusController.fail_safe` (FAST STOP, outputs to zero: the
decision and its reasons are in docs/fidelity.md, "Fieldbus master lost").
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Protocol

from ..protocol import CATALOG, Command, Frame, GripperState, PrepositionFlag, Status, SystemFlag
from .image import JOG, MOTION_COMMANDS, CmdFlag, InputImage, OutputImage, force_scale

if TYPE_CHECKING:
    from .bus import BusAdapter

log = logging.getLogger(__name__)

GS = GripperState
#: Gripper states in which fingers move on a command; a new motion edge is refused (E_ALREADY_RUNNING).
RUNNING_STATES = frozenset({GS.GRIPPING, GS.RELEASING, GS.POSITIONING})
#: The gripper states each motion command may start from. MOVE: 002 §4.1 / 003 §5.1. The rest are
#: decisions (docs/fidelity.md): GRIP like MOVE from IDLE only; RELEASE also takes the part (or the
#: fingers after NO_PART / PART_LOST / ERROR) away; HOMING and jog are the ways out of a bad
#: position, refused only while a part is held.
STARTS_FROM: dict[CmdFlag, frozenset[GripperState]] = {
    CmdFlag.MOVE: frozenset({GS.IDLE}),
    CmdFlag.GRIP: frozenset({GS.IDLE}),
    CmdFlag.RELEASE: frozenset({GS.IDLE, GS.HOLDING, GS.NO_PART, GS.PART_LOST, GS.ERROR}),
    CmdFlag.HOMING: frozenset({GS.IDLE, GS.NO_PART, GS.PART_LOST, GS.ERROR}),
    JOG: frozenset({GS.IDLE, GS.NO_PART, GS.PART_LOST, GS.ERROR}),
}
#: Final status of a motion command → the command that set it (for the ERROR rule).
_MOTION_IDS = {int(Command.HOMING): CmdFlag.HOMING, int(Command.PREPOSITION): CmdFlag.MOVE,
               int(Command.GRIP_PART): CmdFlag.GRIP, int(Command.RELEASE_PART): CmdFlag.RELEASE}


class SnapshotLike(Protocol):
    width: float
    force: float
    gripper_state: GripperState
    flags: SystemFlag


class FieldbusDevice(Protocol):
    """What the controller needs from :class:`pywsg.device.VirtualGripper`."""

    def open_session(self, kind: str, peer: str = ..., deliver: Callable[[Frame], None] | None = ...) -> Any: ...

    def close_session(self, session: Any) -> None: ...

    def handle_frame(self, session: Any, frame: Frame) -> list[Frame]: ...

    def snapshot(self) -> Any: ...

    def jog(self, direction: int, speed: float, force: float) -> Status | int: ...

    def reset_gripper_state(self) -> None: ...


@dataclass
class _State:
    width: float
    force: float
    gripper_state: GripperState
    flags: SystemFlag


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


def _model_name(gripper: Any) -> str:
    profile = getattr(gripper, "profile", None)
    key = getattr(profile, "key", None)
    if isinstance(key, str):
        return key
    for attr in ("model_name", "model"):
        value = getattr(gripper, attr, None)
        if isinstance(value, str):
            return value
        name = getattr(value, "name", None)
        if isinstance(name, str):
            return name
    return "wsg50"


class FieldbusController:
    """Fieldbus interface of one virtual gripper.

    ``write_outputs(image)`` applies a new output image (as a bus cycle would); ``input_image()``
    computes the input image fresh from the gripper's state; ``output_image`` is the last image
    written. ``model`` ("wsg50", "wsg70", ...) selects the force unit; by default it is taken from
    the gripper.
    """

    def __init__(self, gripper: FieldbusDevice, model: str | None = None) -> None:
        self.gripper = gripper
        self.model = (model or _model_name(gripper)).lower()
        self.force_scale = force_scale(self.model)
        self.output_image = OutputImage()
        self.status: int = int(Status.E_SUCCESS)
        self.events: list[Event] = []
        self._pending: int | None = None   # command ID whose final reply sets STATUS
        self._jog_dir = 0
        self._jog_done = False
        # The fieldbus gripper state shown instead of the device's (ERROR after a failed motion, IDLE
        # after FAST STOP) until the next accepted command; _failed is a final error not yet resolved.
        self._shown: GripperState | None = None
        self._failed: tuple[CmdFlag, int] | None = None
        self._listeners: list[Callable[[Event], None]] = []
        self._buses: list[BusAdapter] = []
        self.session = gripper.open_session("fieldbus", peer="fieldbus", deliver=self._deliver)
        self.limits = self._read_limits()

    # --- public --------------------------------------------------------------------------------
    @property
    def output_bytes(self) -> bytes:
        """The 8 output bytes last written by the PLC."""
        return self.output_image.pack()

    def input_image(self) -> InputImage:
        """The input image now (SYSSTATE, WIDTH, FORCE fresh on every call)."""
        snap = self._state()
        state = self._fieldbus_state(snap)
        if self._jog_dir and not self._jog_done:
            if snap.flags & SystemFlag.SF_MOVING:
                # 002 §4.7: the gripper state is RELEASING while jogging.
                if state == GripperState.POSITIONING:
                    state = GripperState.RELEASING
            else:
                # Jog reached an end position or an obstacle: report its result.
                self._jog_done = True
                self.status = int(Status.E_SUCCESS)
        of_flags = int(getattr(self.gripper, "script_of", 0)) & 0xFF
        return InputImage.from_state(state, SystemFlag(int(snap.flags)), float(snap.width),
                                     float(snap.force), self.status, of_flags, self.model)

    def gripper_state(self) -> GripperState:
        """GSTATE as the fieldbus shows it now (see the module docstring)."""
        return self.input_image().state or GS.IDLE

    def _fieldbus_state(self, snap: SnapshotLike) -> GripperState:
        device = GripperState(snap.gripper_state)
        if snap.flags & SystemFlag.SF_FAST_STOP:
            # 002 §4.6 / 003 §5.6: FAST STOP sets the gripper state to IDLE (the device's 41h may say
            # ERROR or HOLDING); it stays IDLE after the acknowledgement until the next command.
            self._shown, self._failed = GS.IDLE, None
        elif self._failed is not None:
            cmd, status = self._failed
            self._failed = None
            if cmd == CmdFlag.GRIP and device == GS.NO_PART:
                # 002 §4.2: "If no part was found, the status code is set to E_CMD_FAILED" (also when
                # the fingers ran into the end stop instead of through the clamping travel).
                self.status = int(Status.E_CMD_FAILED)
            else:
                self._shown = GS.ERROR
                self._emit(f"{cmd.name} failed ({Status.describe(status)}): gripper state ERROR")
        elif self._shown is not None and device in RUNNING_STATES and snap.flags & SystemFlag.SF_MOVING \
                and self._pending is None and not self._jog_dir:
            self._shown = None   # another interface started a motion: show it
        return device if self._shown is None else self._shown

    def _state(self) -> SnapshotLike:
        """The four values the input image needs; cheaper than a full snapshot on every bus read."""
        g: Any = self.gripper
        if all(hasattr(g, a) for a in ("width", "force", "system_flags", "gstate", "clock")):
            now = g.clock()
            return _State(float(g.width(now)), float(g.force(now)), GripperState(g.gstate),
                          SystemFlag(int(g.system_flags(now))))
        snap: SnapshotLike = self.gripper.snapshot()
        return snap

    def input_bytes(self) -> bytes:
        """The 12 input bytes now."""
        return self.input_image().pack()

    def add_listener(self, fn: Callable[[Event], None]) -> None:
        """Call ``fn(event)`` for every command the controller issues."""
        self._listeners.append(fn)

    # --- buses -----------------------------------------------------------------------------------
    @property
    def buses(self) -> tuple[BusAdapter, ...]:
        """The bus adapters feeding this controller, in the order they attached."""
        return tuple(self._buses)

    def attach_bus(self, adapter: BusAdapter) -> None:
        """Register a bus adapter (listed by :attr:`buses`, shown by the Fieldbus Monitor)."""
        if adapter not in self._buses:
            self._buses.append(adapter)

    def detach_bus(self, adapter: BusAdapter) -> None:
        """Forget a bus adapter that stopped serving (no error if it was not attached)."""
        if adapter in self._buses:
            self._buses.remove(adapter)

    def fail_safe(self, bus: str, reason: str) -> None:
        """A bus lost its master: FAST STOP, and the output image falls back to all zeros.

        Called by a bus adapter when its master is gone without saying goodbye (PROFINET AR watchdog
        or abort, PROFIBUS watchdog or Global_Control Clear). As an unannounced TCP close (000
        §1.4.2: "lost connections must be considered as severe errors"), it raises FAST STOP (STATUS =
        E_CMD_ABORTED; a running motion or jog stops; the master acknowledges with STOP/ACK when it
        is back). The outputs the lost master left behind are dropped, as PROFIBUS DP slaves drop
        theirs to the fail-safe value 0: the IF flags clear, no jog level stays raised, and the
        returning master's first image is read against zeros. docs/fidelity.md, "Fieldbus master lost".
        """
        log.warning("fieldbus %s: master lost (%s): FAST STOP", bus, reason)
        self._stop_jog()
        self._raise_fast_stop(f"{bus} master lost ({reason})", Status.E_CMD_ABORTED)
        if self.output_image.if_flags:
            self._set_script_if(0)
        self.output_image = OutputImage()

    def close(self) -> None:
        """Close the controller's device session (stops a running jog)."""
        if self._jog_dir:
            self.gripper.jog(0, 0.0, 0.0)
            self._jog_dir = 0
        self.gripper.close_session(self.session)

    def write_outputs(self, image: OutputImage) -> None:
        """Apply a new output image: edges, jog levels, FAST STOP rules."""
        old, new = self.output_image, image
        self.output_image = new
        if new.if_flags != old.if_flags:
            self._set_script_if(new.if_flags)
        rising = CmdFlag(int(new.cmdflags) & ~int(old.cmdflags) & 0x3F)
        params_changed = (new.width, new.speed, new.force_limit) != (old.width, old.speed, old.force_limit)
        held = new.cmdflags & (CmdFlag.STOP_ACK | CmdFlag.FASTSTOP)

        if params_changed and not self._jog_dir:
            snap = self.gripper.snapshot()
            if snap.flags & SystemFlag.SF_MOVING:
                self._raise_fast_stop("parameter changed while MOVING", Status.E_CMD_ABORTED)
                self._update_jog(new, blocked=True)
                return

        if rising & CmdFlag.FASTSTOP:
            # Safety first: a FASTSTOP edge is executed even if a lower bit rose with it.
            self._raise_fast_stop("FASTSTOP flag", Status.E_SUCCESS)
        elif rising:
            lowest = CmdFlag(int(rising) & -int(rising))
            if lowest == CmdFlag.STOP_ACK:
                self._stop_ack(new)
            elif lowest & MOTION_COMMANDS:
                if held:
                    self._emit(f"{lowest.name} ignored: STOP/ACK or FASTSTOP held at 1")
                    self._set_status(Status.E_ACCESS_DENIED)
                elif self._refused(lowest):
                    pass
                else:
                    self._motion(lowest, new)
        self._update_jog(new, blocked=bool(held))

    def _set_script_if(self, flags: int) -> None:
        set_if = getattr(self.gripper, "set_script_if", None)
        if set_if is not None:
            set_if(flags)   # running scripts are told
        else:
            setattr(self.gripper, "script_if", flags)  # noqa: B010

    # --- commands ------------------------------------------------------------------------------
    def _refused(self, cmd: CmdFlag) -> bool:
        """Check the command's precondition (:data:`STARTS_FROM`); if it fails, say so in STATUS."""
        state = GS.RELEASING if self._jog_dir and not self._jog_done else self.gripper_state()
        if state in STARTS_FROM[cmd]:
            return False
        status = Status.E_ALREADY_RUNNING if state in RUNNING_STATES else Status.E_ACCESS_DENIED
        name = "JOG" if cmd == JOG else cmd.name
        self._emit(f"{name} refused: gripper state {state.name} ({Status.describe(status)})")
        self._set_status(status)
        return True

    def _motion(self, cmd: CmdFlag, out: OutputImage) -> None:
        width, speed, force = out.width / 100, out.speed / 100, out.force_limit / self.force_scale
        lim = self.limits
        max_force = self._max_force()
        problem = None
        if cmd in (CmdFlag.MOVE, CmdFlag.GRIP, CmdFlag.RELEASE):
            if not 0 <= width <= lim.stroke:
                problem = f"WIDTH {width:.2f} mm outside 0..{lim.stroke:g} mm"
            elif not lim.min_speed <= speed <= lim.max_speed:
                problem = f"SPEED {speed:.2f} mm/s outside {lim.min_speed:g}..{lim.max_speed:g} mm/s"
        if problem is None and cmd == CmdFlag.GRIP and not lim.min_force <= force <= max_force:
            problem = f"FORCELIMIT {force:g} N outside {lim.min_force:g}..{max_force:g} N"
        if problem is None and cmd == CmdFlag.MOVE and out.force_limit and \
                not lim.min_force <= force <= max_force:
            problem = f"FORCELIMIT {force:g} N outside {lim.min_force:g}..{max_force:g} N"
        if problem is not None:
            self._raise_fast_stop(f"{cmd.name}: {problem}", Status.E_RANGE_ERROR)
            return

        frames: list[tuple[Command, dict[str, Any]]] = []
        if cmd == CmdFlag.HOMING:
            frames.append((Command.HOMING, {"direction": 0}))
        elif cmd == CmdFlag.MOVE:
            if out.force_limit:
                frames.append((Command.SET_FORCE_LIMIT, {"force": force}))
            # Stop on a block: a MOVE into an obstacle ends (E_AXIS_BLOCKED → ERROR) instead of
            # clamping on in POSITIONING with no end (docs/fidelity.md).
            frames.append((Command.PREPOSITION, {"flags": int(PrepositionFlag.STOP_ON_BLOCK), "width": width,
                                                 "speed": speed}))
        elif cmd == CmdFlag.GRIP:
            frames.append((Command.SET_FORCE_LIMIT, {"force": force}))
            frames.append((Command.GRIP_PART, {"width": width, "speed": speed}))
        elif cmd == CmdFlag.RELEASE:
            frames.append((Command.RELEASE_PART, {"width": width, "speed": speed}))
        self._emit(f"{cmd.name} width={width:.2f} mm speed={speed:.2f} mm/s force={force:g} N")
        if self._run(frames):
            self._shown = None   # accepted: the gripper state is the command's from here

    def _stop_ack(self, out: OutputImage) -> None:
        snap = self.gripper.snapshot()
        if snap.flags & SystemFlag.SF_FAST_STOP:
            if out.cmdflags & CmdFlag.FASTSTOP:
                self._emit("STOP/ACK ignored: reset FASTSTOP before acknowledging")
                self._set_status(Status.E_ACCESS_DENIED)
                return
            self._emit("STOP/ACK: acknowledge FAST STOP")
            if not self._run([(Command.ACK_FAST_STOP, {"key": "ack"})]):
                return
        else:
            self._emit("STOP/ACK: stop")
        self._stop_jog()
        if self._run([(Command.STOP, {})]):
            self._shown, self._failed = None, None
            if self.gripper.snapshot().gripper_state != GripperState.IDLE:
                # 002 §4.5: STOP/ACK sets the gripper state to IDLE (also from ERROR, HOLDING, NO_PART),
                # which 22h alone does not do when no motion was running.
                self.gripper.reset_gripper_state()

    def _raise_fast_stop(self, reason: str, status: Status) -> None:
        self._emit(f"FAST STOP: {reason}")
        self._stop_jog()
        self._run([(Command.FAST_STOP, {})])
        self._shown, self._failed = GS.IDLE, None   # 002 §4.6 / 003 §5.6
        self._set_status(status)

    def _update_jog(self, out: OutputImage, blocked: bool) -> None:
        bits = out.cmdflags & JOG
        direction = 1 if bits == CmdFlag.JOG_PLUS else -1 if bits == CmdFlag.JOG_MINUS else 0
        if direction == self._jog_dir:
            if direction and (out.speed, out.force_limit) != (self._jog_params):
                self._start_jog(direction, out)   # hand wheel: new speed / force while jogging
            return
        if direction == 0:
            self._emit("JOG stop" if bits else "JOG mode left")
            self._stop_jog()
            self._set_status(Status.E_SUCCESS)
            return
        if blocked:
            self._stop_jog()
            self._set_status(Status.E_ACCESS_DENIED)
            return
        snap = self.gripper.snapshot()
        if snap.flags & SystemFlag.SF_FAST_STOP:
            self._stop_jog()
            self._set_status(Status.E_ACCESS_DENIED)
            return
        if not self._jog_dir and self._refused(JOG):
            return
        speed, force = out.speed / 100, out.force_limit / self.force_scale
        if speed > self.limits.max_speed or force > self._max_force() or force < 0:
            self._raise_fast_stop(f"JOG: SPEED {speed:g} mm/s / FORCELIMIT {force:g} N beyond limits",
                                  Status.E_RANGE_ERROR)
            return
        self._start_jog(direction, out)

    _jog_params: tuple[int, int] = (0, 0)

    def _start_jog(self, direction: int, out: OutputImage) -> None:
        speed = max(out.speed / 100, self.limits.min_speed)     # SPEED 0: minimum speed (002 §4.7)
        force = out.force_limit / self.force_scale if out.force_limit else self._current_force_limit()
        speed = min(speed, self.limits.max_speed)
        force = min(force, self._max_force())
        self._emit(f"JOG{'+' if direction > 0 else '-'} speed={speed:.2f} mm/s force={force:g} N")
        self._pending = None
        if direction == self._jog_dir:
            self.gripper.jog(0, 0.0, 0.0)   # the device keeps a running jog's speed: restart it
        status = int(self.gripper.jog(direction, speed, force))
        if status != Status.E_SUCCESS:
            self._emit(f"JOG refused: {Status.describe(status)}")
            self._set_status(status)
            self._jog_dir = 0
            return
        self._jog_dir = direction
        self._jog_done = False
        self._shown = None
        self._jog_params = (out.speed, out.force_limit)
        self._set_status(Status.E_CMD_PENDING)

    def _stop_jog(self) -> None:
        if self._jog_dir:
            self._jog_dir = 0
            self.gripper.jog(0, 0.0, 0.0)

    # --- helpers -------------------------------------------------------------------------------
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
