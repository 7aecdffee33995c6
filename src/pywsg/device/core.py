"""The device core: one gripper's state and the rules that tie its parts together, without any wire format.

:class:`DeviceCore` owns the parts — the :class:`~pywsg.device.axis.Axis` (what the fingers do), the
:class:`~pywsg.device.schedule.Schedule`, the :class:`~pywsg.device.streams.Streams`, the
:class:`~pywsg.device.health.Health` (temperature and fault latches), the fingers and the plugins — and
the device-wide rules between them: FAST STOP (000 §3.2.4/3.2.5), what faults and temperature do to a
motion (Appendix B), time advancing through internal events, and readings in closed form. The command
handlers (:mod:`pywsg.device.handlers`) and the facade (:class:`~pywsg.device.gripper.VirtualGripper`)
are built on top; plugins and fault injection see it only through small Protocols
(:class:`~pywsg.device.plugins.base.ScriptHost`, :class:`~pywsg.device.faults.FaultTarget`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from ..protocol import CATALOG, FingerType, Frame, GripperState, Status, SystemFlag
from .axis import POS_EPS, SF_BLOCKED, SPEED_EPS, Axis, AxisEvent, Motion
from .clock import Clock
from .faults import Faults, Obstacle
from .fingers import Finger
from .health import Health
from .log import LogLevel, SystemLog
from .motion import Trajectory
from .plugins import PLUGINS, FirmwarePlugin
from .profiles import Profile
from .schedule import Schedule
from .session import Session
from .settings import Settings
from .streams import Streams
from .thermal import ThermalModel

S = Status
GS = GripperState

_SF_CMD_FAILURE = int(SystemFlag.SF_CMD_FAILURE)
_SF_FAST_STOP = int(SystemFlag.SF_FAST_STOP)
_SF_FINGER_FAULT = int(SystemFlag.SF_FINGER_FAULT)
_SF_FORCECNTL_MODE = int(SystemFlag.SF_FORCECNTL_MODE)
_SF_MOVING = int(SystemFlag.SF_MOVING)
_SF_OVERDRIVE_MODE = int(SystemFlag.SF_OVERDRIVE_MODE)
_SF_REFERENCED = int(SystemFlag.SF_REFERENCED)
_SF_SCRIPT_FAILURE = int(SystemFlag.SF_SCRIPT_FAILURE)
_SF_SCRIPT_RUNNING = int(SystemFlag.SF_SCRIPT_RUNNING)
_SF_SOFT_LIMIT_MINUS = int(SystemFlag.SF_SOFT_LIMIT_MINUS)
_SF_SOFT_LIMIT_PLUS = int(SystemFlag.SF_SOFT_LIMIT_PLUS)
# plain ints for the hot paths (comparing with an IntEnum member looks it up on the class each time)
_ID_SYSTEM_STATE = 0x40
_ID_GRIPPER_STATE = 0x41
_ID_WIDTH = 0x43
_ID_SPEED = 0x44


@dataclass(frozen=True)
class Snapshot:
    """The device state at ``time`` (closed-form), for the web UI, the fieldbus and tests.

    Units: width mm, speed mm/s (signed, of the opening width), force N, temperature °C.
    """

    time: float
    width: float
    speed: float
    force: float
    gripper_state: GripperState
    flags: SystemFlag
    temperature: float
    force_limit: float
    acceleration: float
    soft_limits: tuple[float, float] | None
    referenced: bool
    moving: bool
    target: float | None
    overdrive: bool
    fast_stop: bool
    model: str
    stroke: float
    statistics: tuple[int, int, int]
    tag: str | None
    part: float | None
    blocked_at: float | None
    script_if: int
    script_of: int
    plugins: tuple[str, ...] = field(default_factory=tuple)


class DeviceCore:
    """State and device-wide rules of one virtual gripper (see the module docstring)."""

    # set by the facade at power-up (VirtualGripper._power_up)
    settings: Settings
    profile: Profile
    serial_number: int
    axis: Axis
    tag: str | None
    fingers: list[Finger]
    thermal: ThermalModel
    health: Health
    script_if: int
    script_of: int
    script_failure: bool
    ack_refused = False
    """World fault "acknowledge refused": 24h answers E_ACCESS_DENIED as while a fault persists."""

    def __init__(self, clock: Clock) -> None:
        self.clock: Clock = clock
        self.log = SystemLog()
        self.faults = Faults(self)
        self.schedule = Schedule()
        self.streams = Streams(self.schedule, self.value_for, self.moving)
        self.plugins: dict[str, FirmwarePlugin] = {}
        self._plugin_cmds: dict[int, FirmwarePlugin] = {}
        self._event: AxisEvent | None = None
        self._bits = 0  # latched device flags: FAST_STOP, CMD_FAILURE

    # ------------------------------------------------------------------ the axis' values, as before the split

    @property
    def gstate(self) -> GripperState:
        """The 41h gripper state."""
        return self.axis.gstate

    @gstate.setter
    def gstate(self, value: GripperState) -> None:
        self.axis.gstate = value

    @property
    def referenced(self) -> bool:
        return self.axis.referenced

    @property
    def acceleration(self) -> float:
        """mm/s² (30h/31h)."""
        return self.axis.acceleration

    @property
    def force_limit(self) -> float:
        """N (32h/33h)."""
        return self.axis.force_limit

    @property
    def soft_limits(self) -> tuple[float, float] | None:
        """(minus, plus) in mm (34h–36h), or None."""
        return self.axis.soft_limits

    @property
    def overdrive(self) -> bool:
        return self.axis.overdrive

    @property
    def obstacles(self) -> dict[str, Obstacle]:
        return self.axis.obstacles

    @property
    def power_fault(self) -> bool:
        """SF_POWER_FAULT is raised (fault injection)."""
        return self.health.power_fault

    @property
    def current_fault(self) -> bool:
        """SF_CURR_FAULT is raised (fault injection)."""
        return self.health.current_fault

    @property
    def stats(self) -> list[int]:
        """42h gripping statistics: grips, no part, part lost."""
        return self.axis.stats

    # ------------------------------------------------------------------ time

    def changed(self) -> None:
        self.schedule.changed()

    def notify(self) -> None:
        self.schedule.notify()

    def reschedule(self, now: float) -> None:
        """Recompute the next internal event (motion, timer, temperature threshold)."""
        self._event = self.axis.next_event(now)
        t = self._event[0] if self._event is not None else math.inf
        t = min(t, self.schedule.next_timer())
        c = self.health.next_crossing(now)
        if c is not None and c < t:
            t = c
        self.schedule.next_event = t
        self.schedule.due_valid = False

    def advance(self, now: float) -> None:
        """Process every internal event up to ``now``, in time order."""
        guard = 0
        schedule = self.schedule
        while schedule.next_event <= now:
            guard += 1
            if guard > 10000:  # pragma: no cover - defensive
                raise RuntimeError("event loop does not converge")
            t = schedule.next_event
            if self._event is not None and self._event[0] <= t:
                ev = self._event
                self._event = None
                self.axis.on_event(ev[0], ev[2], ev[3])
                self.changed()
            elif schedule.next_timer() <= t:
                _, _, kind, args = schedule.pop_timer()
                self._on_timer(t, kind, args)
            else:
                self._update_temp_flags(t + 1e-9)  # just past the crossing so the new state is seen
            self.reschedule(t)
        self._update_temp_flags(now)

    def add_timer(self, t: float, kind: str, *args: object) -> None:
        self.schedule.add_timer(t, kind, args)
        self.reschedule(self.clock())

    def _on_timer(self, t: float, kind: str, args: tuple[object, ...]) -> None:
        if kind == "finger_power":
            n, s, cid = args
            assert isinstance(n, int) and isinstance(cid, int)
            f = self.fingers[n]
            if f.powering_until is not None and f.powering_until <= t:
                f.powering_until = None
                f.powered = True
                self.streams.emit(s if isinstance(s, Session) else None, Frame.reply(cid, S.E_SUCCESS))
                self.changed()
        elif kind == "call":  # a world fault's timer (pywsg.testing.world_faults): fn(t)
            fn = args[0]
            if callable(fn):
                fn(t)

    # ------------------------------------------------------------------ motion (AxisHost and helpers)

    def final_reply(self, motion: Motion, status: Status) -> None:
        """AxisHost: a motion with a deferred reply ended."""
        assert motion.command_id is not None
        self.streams.emit(motion.session, Frame.reply(motion.command_id, status))
        if status != S.E_SUCCESS:
            self._bits |= _SF_CMD_FAILURE

    def motion_locked(self) -> bool:
        """FAST STOP, a temperature fault or a power/current fault forbids any motion."""
        return bool(self._bits & _SF_FAST_STOP) or self.health.locked()

    def motion_denied(self, now: float, need_reference: bool = True,
                      replaces: tuple[str, ...] = ()) -> Status | None:
        """Why a motion may not start now, or None. ``replaces``: motion kinds it may supersede."""
        if self.motion_locked():
            return S.E_ACCESS_DENIED
        if self.axis.busy(now, replaces):
            return S.E_ALREADY_RUNNING
        if need_reference and not self.axis.referenced:
            return S.E_NOT_INITIALIZED
        return None

    def start_motion(self, now: float, motion: Motion, traj: Trajectory) -> None:
        self.axis.start(now, motion, traj)
        self.reschedule(now)
        self.changed()

    def abort_motion(self, status: Status, now: float) -> bool:
        """Stop a running motion (or clamping); returns True if one was running."""
        was = self.axis.abort(status, now)
        self.reschedule(now)
        self.changed()
        return was

    def script_stop_if_running(self, now: float) -> None:
        self.axis.stop_script_motion(now)

    # ------------------------------------------------------------------ readings (closed form)

    def width(self, now: float | None = None) -> float:
        """Opening width in mm (0 when not referenced, as the manual says)."""
        if not self.axis.referenced:
            return 0.0
        return self.axis.traj.position(self.clock() if now is None else now)

    def true_width(self, now: float | None = None) -> float:
        """The physical width in mm, referenced or not (differs from 43h after a wrong reference)."""
        return self.axis.traj.position(self.clock() if now is None else now) + self.axis.offset

    def speed(self, now: float | None = None) -> float:
        """Finger speed in mm/s (rate of change of the opening width; negative when closing)."""
        return self.axis.traj.velocity(self.clock() if now is None else now)

    def force(self, now: float | None = None) -> float:
        """Gripping force in N: the force limit while holding, 50 % nominal while clamping, else 0."""
        return self.axis.force()

    def temperature(self, now: float | None = None) -> float:
        return self.thermal.temperature(self.clock() if now is None else now)

    def moving(self, now: float | None = None) -> bool:
        return self.axis.traj.is_moving(self.clock() if now is None else now)

    def blocked(self) -> bool:
        return bool(self.axis.bits & SF_BLOCKED)

    def value_for(self, cid: int, now: float) -> float | int:
        """The value an auto-update command (40h, 41h, 43h–45h) reports at ``now``."""
        if cid == _ID_WIDTH:
            return self.width(now)
        if cid == _ID_SYSTEM_STATE:
            return self._flag_bits(now)
        if cid == _ID_GRIPPER_STATE:
            return int(self.axis.gstate)
        if cid == _ID_SPEED:
            return self.speed(now)
        return self.force(now)

    def system_flags(self, now: float | None = None) -> SystemFlag:
        """The 40h system state flags (Appendix B) at ``now``."""
        return SystemFlag(self._flag_bits(self.clock() if now is None else now))

    def _flag_bits(self, now: float) -> int:
        axis = self.axis
        f = self._bits | axis.bits
        if axis.referenced:
            f |= _SF_REFERENCED
            if axis.soft_limits is not None:
                x = axis.traj.position(now)
                if x <= axis.soft_limits[0] + POS_EPS:
                    f |= _SF_SOFT_LIMIT_MINUS
                if x >= axis.soft_limits[1] - POS_EPS:
                    f |= _SF_SOFT_LIMIT_PLUS
        if axis.traj.is_moving(now):
            f |= _SF_MOVING
        if axis.overdrive:
            f |= _SF_OVERDRIVE_MODE
        if axis.gstate in (GS.GRIPPING, GS.HOLDING) and any(
                fg.type == FingerType.WSG_FMF and fg.powered and not fg.fault for fg in self.fingers):
            f |= _SF_FORCECNTL_MODE
        f |= self.health.flag_bits()
        f0, f1 = self.fingers
        if f0.fault or f0.comm_fault or f1.fault or f1.comm_fault:
            f |= _SF_FINGER_FAULT
        if self.plugins:
            f |= _SF_SCRIPT_RUNNING
        if self.script_failure:
            f |= _SF_SCRIPT_FAILURE
        return f

    @property
    def fast_stopped(self) -> bool:
        return bool(self._bits & _SF_FAST_STOP)

    def snapshot(self) -> Snapshot:
        now = self.clock()
        self.advance(now)
        axis = self.axis
        m = axis.motion
        part = axis.obstacles.get("part")
        block = axis.obstacles.get("block")
        return Snapshot(
            time=now, width=self.width(now), speed=self.speed(now), force=self.force(now),
            gripper_state=axis.gstate, flags=self.system_flags(now), temperature=self.temperature(now),
            force_limit=axis.force_limit, acceleration=axis.acceleration, soft_limits=axis.soft_limits,
            referenced=axis.referenced, moving=self.moving(now), target=m.target if m is not None else None,
            overdrive=axis.overdrive, fast_stop=self.fast_stopped, model=self.profile.key,
            stroke=self.profile.stroke, statistics=(axis.stats[0], axis.stats[1], axis.stats[2]), tag=self.tag,
            part=part.width if part is not None else None, blocked_at=block.width if block is not None else None,
            script_if=self.script_if, script_of=self.script_of, plugins=tuple(self.plugins),
        )

    # ------------------------------------------------------------------ FAST STOP, faults, temperature

    def fast_stop(self, now: float, reason: str) -> None:
        """AxisHost: raise FAST STOP (000 §3.2.4): the fingers stop, a running motion is aborted, and the
        drive is turned off (002 §3.1 bit 5 "Stop and turn off the motor"): no gripping force, a held
        part is let go where it is. 41h goes to ERROR (001 §3.4.2: "… oder ein Fast Stop wurde
        ausgelöst") until the next motion command after the acknowledge."""
        axis = self.axis
        if axis.motion is not None:
            axis.halt(now)
            axis.finish(S.E_CMD_ABORTED)
        c = axis.contact
        # fingers that pressed on something spring back to its surface; otherwise they stop where they are
        axis.halt(now, axis.local(c.obstacle.width) if c is not None else None)
        axis.contact = None
        axis.gstate = GS.ERROR
        self._bits |= _SF_FAST_STOP
        self.log.add(now, LogLevel.ERROR, f"FAST STOP: {reason}")
        axis.update_load(now)
        self.reschedule(now)
        self.changed()
        self.notify()

    def obstacles_changed(self) -> None:
        """Faults moved an obstacle: re-plan events, release or lose what was held."""
        now = self.clock()
        self.advance(now)
        self.axis.obstacles_changed(now)
        self.reschedule(now)
        self.changed()
        self.notify()

    def reset_gripper_state(self) -> None:
        """Fieldbus STOP/ACK (fieldbus manual §5.5): the gripper state goes back to IDLE.

        Unlike 22h Stop, this also leaves HOLDING, NO_PART, PART_LOST and ERROR; a held part's
        gripping force is released (the fingers stay where they are).
        """
        now = self.clock()
        self.advance(now)
        axis = self.axis
        if axis.motion is None:
            axis.contact = None
        axis.gstate = GS.IDLE
        axis.update_load(now)
        self.reschedule(now)
        self.changed()
        self.notify()

    def raise_fast_stop(self, reason: str) -> None:
        """FAST STOP from outside the binary protocol (fieldbus FASTSTOP, parameter change while moving)."""
        now = self.clock()
        self.advance(now)
        self.fast_stop(now, reason)

    def acknowledge_fast_stop(self) -> Status:
        """Acknowledge (24h / fieldbus ACK). E_ACCESS_DENIED while a power or current fault persists."""
        now = self.clock()
        self.advance(now)
        if self.health.power_fault or self.health.current_fault or self.ack_refused:
            return S.E_ACCESS_DENIED
        if self._bits & _SF_FAST_STOP:
            self._bits &= ~_SF_FAST_STOP
            self.log.add(now, LogLevel.INFO, "FAST STOP acknowledged")
            self.changed()
        return S.E_SUCCESS

    def _update_temp_flags(self, now: float) -> None:
        old = self.health.temp_state
        if self.health.update_temperature(now):  # a temperature fault began: a running motion ends
            axis = self.axis
            if axis.motion is not None or (axis.contact is not None and axis.contact.kind != "hold"):
                self.abort_motion(S.E_CMD_ABORTED, now)
                axis.gstate = GS.ERROR
        if self.health.temp_state != old:
            self.changed()

    def heat(self, delta_c: float) -> None:
        now = self.clock()
        self.advance(now)
        self.thermal.heat(now, delta_c)
        self._update_temp_flags(now)
        self.reschedule(now)
        self.changed()
        self.notify()

    def set_power_fault(self, on: bool) -> None:
        """SF_POWER_FAULT: raising it raises FAST STOP; 24h is refused while it persists."""
        if self._fault_changed(on, self.health.power_fault):
            self.health.power_fault = on
            self._fault_raised(on, "power supply out of range", "power supply back in range")

    def set_current_fault(self, on: bool) -> None:
        """SF_CURR_FAULT: raising it raises FAST STOP; 24h is refused while it persists."""
        if self._fault_changed(on, self.health.current_fault):
            self.health.current_fault = on
            self._fault_raised(on, "motor current fault", "motor recovered")

    def _fault_changed(self, on: bool, old: bool) -> bool:
        self.advance(self.clock())
        return on != old

    def _fault_raised(self, on: bool, raised: str, cleared: str) -> None:
        now = self.clock()
        if on:
            self.fast_stop(now, raised)
        else:
            self.log.add(now, LogLevel.INFO, cleared)
        self.changed()
        self.notify()

    def set_finger_fault(self, n: int, on: bool) -> None:
        now = self.clock()
        self.advance(now)
        f = self.fingers[n]
        f.fault = on
        if on:
            f.powered = False
            f.powering_until = None
            self.log.add(now, LogLevel.ERROR, f"finger {n + 1}: over-current")
        self.changed()
        self.notify()

    # ------------------------------------------------------------------ motion API (jog, scripts)

    def jog(self, direction: int, speed: float, force: float) -> Status:
        """Fieldbus JOG: move at ``speed`` mm/s (0: minimum speed) in ``direction`` (+1 open, -1 close)
        until an end stop, an obstacle (pressing with ``force`` N) or a soft limit; 0 stops."""
        now = self.clock()
        self.advance(now)
        if direction == 0:
            if self.axis.jog_stop(now):
                self.reschedule(now)
                self.changed()
                self.notify()
            return S.E_SUCCESS
        denied = self.motion_denied(now, replaces=("jog",))
        if denied is not None:
            return denied
        if self.axis.jog(now, 1 if direction > 0 else -1, speed, force):
            self.reschedule(now)
            self.changed()
            self.notify()
        return S.E_SUCCESS

    def script_move(self, width: float, speed: float, now: float | None = None) -> Status:
        """Script ``mc.move``: position to ``width`` mm at ``speed`` mm/s (a running script motion is
        replaced, from its current speed). ``now``: the request's clock reading (one per request)."""
        now = self.clock() if now is None else now
        self.advance(now)
        denied = self.motion_denied(now, replaces=("script",))
        if denied is not None:
            return denied
        self.axis.script_move(now, width, speed)
        self.reschedule(now)
        self.changed()
        self.notify()
        return S.E_SUCCESS

    def script_speed(self, velocity: float, force: float | None = None, now: float | None = None) -> Status:
        """Script ``mc.speed``: run at ``velocity`` mm/s (signed; 0 stops) until blocked, then press with
        ``force`` N (None: the force limit). ``now``: the request's clock reading."""
        now = self.clock() if now is None else now
        self.advance(now)
        if abs(velocity) < SPEED_EPS:
            if self.axis.script_halt(now):
                self.reschedule(now)
                self.changed()
            return S.E_SUCCESS
        denied = self.motion_denied(now, replaces=("script",))
        if denied is not None:
            return denied
        if self.axis.script_speed(now, velocity, force):
            self.reschedule(now)
            self.changed()
            self.notify()
        return S.E_SUCCESS

    def script_stop(self, now: float | None = None) -> None:
        """Script ``mc.stop``: a script motion stops, pressing ends, the BLOCKED flags clear."""
        now = self.clock() if now is None else now
        self.advance(now)
        self.axis.script_stop(now)
        self.reschedule(now)
        self.changed()

    def set_script_if(self, value: int) -> None:
        """The fieldbus IF user flags (16 bits) changed; running plugins are told."""
        value &= 0xFFFF
        if value == self.script_if:
            return
        self.script_if = value
        for plugin in list(self.plugins.values()):
            try:
                plugin.on_if_changed(self, value)
            except Exception as exc:  # a script error aborts the script (000 App. B D20 SF_SCRIPT_FAILURE)
                self.abort_script(plugin.name, exc)
        self.changed()

    def set_script_of(self, value: int) -> None:
        """Set the OF user flags (16 bits), as a script would."""
        self.script_of = value & 0xFFFF
        self.changed()

    # ------------------------------------------------------------------ plugins

    def load_plugin(self, plugin: str | FirmwarePlugin) -> FirmwarePlugin:
        """Start a firmware plugin (by name or instance); its command IDs become known."""
        inst = PLUGINS[plugin]() if isinstance(plugin, str) else plugin
        for cid in inst.commands:
            if cid in CATALOG:
                raise ValueError(f"plugin {inst.name}: command {cid:02X}h belongs to the firmware")
            other = self._plugin_cmds.get(cid)
            if other is not None and other is not inst:
                raise ValueError(f"plugin {inst.name}: command {cid:02X}h already registered by {other.name}")
        self.plugins[inst.name] = inst
        for cid in inst.commands:
            self._plugin_cmds[cid] = inst
        self.script_failure = False  # "reset whenever a script is started" (000 App. B, D20)
        self.log.add(self.clock(), LogLevel.INFO, f"script {inst.name} started")
        try:
            inst.start(self)
        except Exception as exc:
            self.abort_script(inst.name, exc)
        self.changed()
        return inst

    def abort_script(self, name: str, error: BaseException) -> None:
        """A script failed while running: it is aborted and SF_SCRIPT_FAILURE set (000 App. B, flag D20).

        "An error occurred while executing a script and the script has been aborted. The flag is
        reset whenever a script is started." Its command IDs answer E_CMD_UNKNOWN from now on.
        """
        self.log.add(self.clock(), LogLevel.ERROR,
                     f"script {name} aborted: {type(error).__name__}: {error}".rstrip(": "))
        self.unload_plugin(name)
        self.script_failure = True
        self.changed()

    def unload_plugin(self, name: str) -> None:
        inst = self.plugins.pop(name, None)
        if inst is None:
            return
        for cid in inst.commands:
            if self._plugin_cmds.get(cid) is inst:
                del self._plugin_cmds[cid]
        inst.stop(self)
        self.log.add(self.clock(), LogLevel.INFO, f"script {name} stopped")
        self.changed()
