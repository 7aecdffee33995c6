"""What the fingers do: the axis, its trajectory, contact with obstacles and the grip state machine.

One :class:`Axis` per device holds the motion configuration (000 §3.3: acceleration, force limit,
soft limits, overdrive), the reference (§3.2.1), the 41h gripper state and the flags that belong to
motion (Appendix B: AXIS_STOPPED, TARGET_POS_REACHED, BLOCKED_MINUS/PLUS). It answers "when is the
next thing going to happen to the fingers" (:meth:`Axis.next_event`) and "what happens then"
(:meth:`Axis.on_event`). It never talks to a client: a motion's final reply and a FAST STOP go out
through the small :class:`AxisHost` interface; scheduling is the caller's job.

Units: width mm, speed mm/s (of the opening width), acceleration mm/s², force N, time s.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

from ..protocol import GripperState, Status, SystemFlag
from .faults import Obstacle
from .log import LogLevel, SystemLog
from .motion import Trajectory, plan_move, plan_velocity
from .profiles import Profile
from .session import Session
from .thermal import ThermalModel

S = Status
GS = GripperState

SOFT_EPS = 1e-6  # mm: a soft limit is violated only strictly beyond it
POS_EPS = 1e-6
SPEED_EPS = 1e-6
MOTION_TIMEOUT_S = 1.0  # s past a motion's planned end: a release that cannot get there ends E_TIMEOUT
CLAMP_FORCE_RATIO = 0.5  # of the nominal force: pushing on after a block (000 §3.2.2 "Clamp on block")

SF_AXIS_STOPPED = int(SystemFlag.SF_AXIS_STOPPED)
SF_BLOCKED_MINUS = int(SystemFlag.SF_BLOCKED_MINUS)
SF_BLOCKED_PLUS = int(SystemFlag.SF_BLOCKED_PLUS)
SF_TARGET_POS_REACHED = int(SystemFlag.SF_TARGET_POS_REACHED)
SF_BLOCKED = SF_BLOCKED_MINUS | SF_BLOCKED_PLUS
_MOTION_BITS = SF_AXIS_STOPPED | SF_TARGET_POS_REACHED | SF_BLOCKED

AxisEvent = tuple[float, int, str, object]
"""(time, priority, kind, data): kind ``end``, ``contact`` (data: the Obstacle), ``hard`` (data: the end
stop's width and direction), ``soft`` (data: the soft limit's width), ``timeout``."""


@dataclass(slots=True)
class Motion:
    """The motion in progress and what to answer when it ends.

    ``kind``: homing, prepos, grip, release, jog, script, snap (obstacle removed while clamping).
    """

    kind: str
    session: Session | None
    command_id: int | None
    target: float
    speed: float
    direction: int
    stop_on_block: bool = True
    nominal: float = 0.0  # grip: nominal part width
    force: float = 0.0  # jog / script: pressing force when blocked
    deadline: float = math.inf  # release: E_TIMEOUT if the target is not reached by then
    stalled: bool = False  # release: blocked, pushing on until the obstacle goes or the deadline
    velocity_mode: bool = False  # jog / script speed: run at ``speed`` until stopped or blocked


@dataclass(slots=True)
class Contact:
    """Fingers resting on an obstacle: holding a part, clamping (21h), or pressing (jog/script)."""

    obstacle: Obstacle
    direction: int  # direction the fingers push in
    force: float  # N
    kind: str  # hold, clamp (21h clamp on block), press (jog/script), stall (26h blocked)
    target: float = 0.0  # clamp: where to snap when the obstacle goes
    speed: float = 0.0
    nominal: float = 0.0
    resume: Motion | None = None  # press of a script motion: it goes on when the obstacle goes


class AxisHost(Protocol):
    """What the axis needs from the device around it."""

    def final_reply(self, motion: Motion, status: Status) -> None:
        """The motion ended: send its deferred reply (if it has a session) with ``status``."""

    def fast_stop(self, now: float, reason: str) -> None:
        """Raise FAST STOP (a soft limit was crossed)."""


class Axis:
    """The fingers and their state machine (41h), evaluated in closed form on the device's clock."""

    def __init__(self, host: AxisHost, profile: Profile, log: SystemLog, thermal: ThermalModel, now: float,
                 acceleration: float, force_limit: float, clamping_travel: float) -> None:
        self.host = host
        self.profile = profile
        self.log = log
        self.thermal = thermal
        self.clamping_travel = clamping_travel  # mm, from the settings
        self.acceleration = profile.clamp_acc(acceleration)
        self.force_limit = min(max(force_limit, profile.min_force), profile.nom_force)
        self.soft_limits: tuple[float, float] | None = None
        self.overdrive = False
        self.referenced = False
        # true width − reported width (mm): 0 unless homing stopped on an obstacle (000 §3.2.1 "wrong
        # reference point"). The trajectory, targets and readings are in reported (referenced) mm;
        # obstacles and the mechanical end stops are where they physically are.
        self.offset = 0.0
        self._gstate = GS.IDLE
        # (old, new) for every gripper-state change while the device has state listeners, else None;
        # the device hands them out when the call that made them is done (never mid-update).
        self.transitions: list[tuple[GS, GS]] | None = None
        self.traj = Trajectory.rest(now, profile.stroke / 2)  # unknown position until homing
        self.motion: Motion | None = None
        self.contact: Contact | None = None
        self.bits = 0  # latched motion flags: AXIS_STOPPED, TARGET_POS_REACHED, BLOCKED_MINUS/PLUS
        self.obstacles: dict[str, Obstacle] = {}
        # a motion that starts from a held part and heads into it meets it at once (000 §3.2.2 FLAGS D1:
        # "a blocking condition towards the movement direction"), even when the part was squeezed
        self.blocked_at_start: Obstacle | None = None
        self.stats = [0, 0, 0]  # 42h: grips, no part, part lost

    @property
    def gstate(self) -> GS:
        """The gripper state (41h)."""
        return self._gstate

    @gstate.setter
    def gstate(self, value: GS) -> None:
        old = self._gstate
        if value != old:
            self._gstate = value
            if self.transitions is not None:
                self.transitions.append((old, value))

    # ------------------------------------------------------------------ readings

    def local(self, true_width: float) -> float:
        """A physical width (obstacle, end stop) in the axis' reported coordinates."""
        return true_width - self.offset

    def touching(self, x: float) -> Obstacle | None:
        """The obstacle the fingers rest on at reported width ``x``, if any."""
        for ob in self.obstacles.values():
            if abs(ob.width - self.offset - x) <= POS_EPS:
                return ob
        return None

    def max_force(self) -> float:
        return self.profile.ovr_force if self.overdrive else self.profile.nom_force

    def force(self) -> float:
        """Gripping force in N: the force limit while holding, 50 % nominal while clamping, else 0."""
        c = self.contact
        return c.force if c is not None else 0.0

    def holding(self) -> bool:
        c = self.contact
        return c is not None and c.kind == "hold"

    def soft_range_error(self, target: float) -> bool:
        """True if ``target`` lies inside a restricted area (soft limits)."""
        if self.soft_limits is None:
            return False
        lo, hi = self.soft_limits
        return target < lo - SOFT_EPS or target > hi + SOFT_EPS

    def busy(self, now: float, replaces: tuple[str, ...] = ()) -> bool:
        """A motion runs that a new one may not supersede (``replaces``: kinds it may)."""
        m = self.motion
        return (m is not None or self.traj.is_moving(now)) and (m is None or m.kind not in replaces)

    # ------------------------------------------------------------------ events

    def next_event(self, now: float) -> AxisEvent | None:
        """Earliest of: target reached, contact with an obstacle, end stop, soft-limit entry."""
        tr = self.traj
        m = self.motion
        if m is None:
            return None
        if m.stalled:
            return (max(now, m.deadline), 1, "timeout", None)
        if self.blocked_at_start is not None:
            return (max(now, tr.start_time), 0, "contact", self.blocked_at_start)
        if not tr.moving:
            return (max(now, tr.start_time), 1, "end", None)
        best: AxisEvent | None = None
        if math.isfinite(tr.end_time):
            best = (tr.end_time, 1, "end", None)
        if math.isfinite(m.deadline) and (best is None or (m.deadline, 4) < best[:2]):
            best = (m.deadline, 4, "timeout", None)
        for ob in self.obstacles.values():
            t = tr.first_crossing(ob.width - self.offset, ob.blocks, after=now)
            if t is not None and (best is None or (t, 0) < best[:2]):
                best = (t, 0, "contact", ob)
        # moves stay inside the stroke, homing ends on the end stop; jogs, and any move after a wrong
        # reference, can run into a mechanical end stop
        if not math.isfinite(tr.end_time) or (self.offset != 0.0 and m.kind != "homing"):
            stroke = self.profile.stroke
            for p, d in ((-self.offset, -1), (stroke - self.offset, 1)):
                t = tr.first_crossing(p, d, after=now)
                if t is not None and (best is None or (t, 2) < best[:2]):
                    best = (t, 2, "hard", (p, d))
        if self.soft_limits is not None and m.kind != "homing" and self.referenced:
            lo, hi = self.soft_limits
            x = tr.position(now)
            for p, d, ok in ((lo - SOFT_EPS, -1, x >= lo - SOFT_EPS), (hi + SOFT_EPS, 1, x <= hi + SOFT_EPS)):
                if not ok:
                    continue
                t = tr.first_crossing(p, d, after=now)
                if t is not None and (best is None or (t, 3) < best[:2]):
                    best = (t, 3, "soft", p)
        return best

    def on_event(self, t: float, kind: str, data: object) -> None:
        m = self.motion
        if m is None:
            return
        if kind == "end":
            self._on_end(t, m)
        elif kind == "contact":
            assert isinstance(data, Obstacle)
            self._on_contact(t, m, data)
        elif kind == "hard":
            assert isinstance(data, tuple)
            p, d = data
            self.halt(t, p)
            self.bits |= SF_BLOCKED_PLUS if d > 0 else SF_BLOCKED_MINUS
            if m.kind == "release":  # 26h lists no blocked status: push on until the timeout
                self._stall(m)
                return
            self.motion = None
            if m.kind == "prepos":  # 000 §3.2.2: "A limit (either soft or hard limit) was reached"
                self.gstate = GS.ERROR
                self._finish_with(m, S.E_RANGE_ERROR)
            elif m.kind == "grip":  # fully closed (or open) on the end stop: no part found
                self.gstate = GS.NO_PART
                self.stats[1] += 1
                self._finish_with(m, S.E_CMD_FAILED)
            elif m.kind == "jog" or m.kind == "script":
                self.gstate = GS.IDLE
        elif kind == "timeout":
            self.contact = None  # the drive gives up pushing
            self.motion = None
            self.gstate = GS.ERROR
            self.log.add(t, LogLevel.ERROR, f"{m.kind}: target {m.target:.2f} mm not reached in time")
            self._finish_with(m, S.E_TIMEOUT)
        elif kind == "soft":
            assert isinstance(data, float)
            self.halt(t, data)
            self.host.fast_stop(t, f"soft limit violated at {data:.2f} mm")
        self.update_load(t)

    # ------------------------------------------------------------------ starting and stopping

    def start(self, now: float, motion: Motion, traj: Trajectory) -> None:
        held = self.contact
        self.blocked_at_start = None
        if held is not None and held.kind == "hold" and motion.direction == held.direction and motion.kind != "grip":
            self.blocked_at_start = held.obstacle  # a re-grip (25h) lifts off the part first: handlers.grip
        self.bits &= ~_MOTION_BITS
        self.contact = None
        self.motion = motion
        self.traj = traj
        self.update_load(now)

    def halt(self, now: float, x: float | None = None) -> None:
        """Fingers stop at once (at ``x`` if given)."""
        self.blocked_at_start = None
        pos = self.traj.position(now) if x is None else x
        self.traj = Trajectory.rest(now, pos)

    def finish(self, status: Status) -> None:
        """Send the running motion's final reply (if it has one) and forget the motion."""
        m = self.motion
        self.motion = None
        if m is not None and m.command_id is not None:
            self.host.final_reply(m, status)

    def _finish_with(self, m: Motion, status: Status) -> None:
        self.motion = m
        self.finish(status)

    def abort(self, status: Status, now: float) -> bool:
        """Stop a running motion (or clamping); returns True if one was running."""
        was = self.motion is not None
        self.halt(now)
        if was:
            self.finish(status)
        if self.contact is not None and self.contact.kind != "hold":
            self.contact = None
        self.update_load(now)
        return was

    def stop_script_motion(self, now: float) -> None:
        """A firmware command takes over from a jog or a script motion."""
        m = self.motion
        if m is not None and m.kind in ("jog", "script"):
            self.halt(now)
            self.motion = None

    def update_load(self, now: float) -> None:
        """Tell the thermal model what the motor does now (holding force, moving)."""
        c = self.contact
        ratio = c.force / self.profile.nom_force if c is not None else 0.0
        self.thermal.set_load(now, ThermalModel.rise_for(ratio, self.traj.is_moving(now)))

    # ------------------------------------------------------------------ outcomes

    def _on_end(self, t: float, m: Motion) -> None:
        x = self.traj.final_x if self.traj.moving else self.traj.position(t)
        self.motion = None
        if m.kind == "homing":  # on the mechanical end stop: the reference is right again
            x = self.profile.stroke if m.direction > 0 else 0.0
            self.offset = 0.0
        self.halt(t, x)
        if m.kind == "homing":
            self.referenced = True
            self.gstate = GS.IDLE
            self.bits |= SF_TARGET_POS_REACHED
            self.log.add(t, LogLevel.INFO, f"homing done at {x:.2f} mm")
            self._finish_with(m, S.E_SUCCESS)
        elif m.kind in ("prepos", "release", "script"):
            self.gstate = GS.IDLE
            self.bits |= SF_TARGET_POS_REACHED
            self._finish_with(m, S.E_SUCCESS)
        elif m.kind == "snap":  # the clamp's 21h already answered E_AXIS_BLOCKED: its ERROR stays
            self.bits |= SF_TARGET_POS_REACHED
        elif m.kind == "grip":
            # fell through the clamping travel without establishing the force
            self.gstate = GS.NO_PART
            self.stats[1] += 1
            self._finish_with(m, S.E_CMD_FAILED)
        else:  # jog: cannot end by itself
            self.gstate = GS.IDLE

    def _on_contact(self, t: float, m: Motion, ob: Obstacle) -> None:
        # from a held (squeezed) part the fingers stop where they are; else on the obstacle's surface
        x = self.traj.position(t) if self.blocked_at_start is ob else ob.width - self.offset
        self.blocked_at_start = None
        d = m.direction
        blocked_bit = SF_BLOCKED_PLUS if d > 0 else SF_BLOCKED_MINUS
        if m.kind == "grip":
            lo, hi = m.nominal - self.clamping_travel, m.nominal + self.clamping_travel
            if ob.kind == "part" and lo - POS_EPS <= x <= hi + POS_EPS:
                force = self.force_limit
                squeeze = 0.0 if math.isinf(ob.stiffness) else force / ob.stiffness
                self.halt(t, x + d * squeeze)
                self.contact = Contact(ob, d, force, "hold", nominal=m.nominal)
                self.gstate = GS.HOLDING
                self._finish_with(m, S.E_SUCCESS)
            else:
                self.halt(t, x)
                self.gstate = GS.NO_PART
                self.stats[1] += 1
                self.bits |= blocked_bit
                self._finish_with(m, S.E_CMD_FAILED)
            return
        if m.kind == "homing":
            self._wrong_reference(t, m, x)
            return
        self.halt(t, x)
        self.bits |= blocked_bit
        if m.kind == "prepos":
            if not m.stop_on_block:  # clamp on block: keep pushing with half the nominal force, snap when freed
                force = CLAMP_FORCE_RATIO * self.profile.nom_force
                self.contact = Contact(ob, d, force, "clamp", m.target, m.speed)
            self.gstate = GS.ERROR  # the command failed (41h "Error": an error during the process)
            self._finish_with(m, S.E_AXIS_BLOCKED)
        elif m.kind == "release":
            self.contact = Contact(ob, d, CLAMP_FORCE_RATIO * self.profile.nom_force, "stall", m.target, m.speed)
            self._stall(m)
        elif m.kind in ("jog", "script"):
            # a script's mc.move / mc.speed stays commanded while blocked (cmd_measure.lua "keeps pushing")
            self.contact = Contact(ob, d, m.force, "press", m.target, m.speed,
                                   resume=m if m.kind == "script" else None)
            self.motion = None
            if m.kind == "jog":
                self.gstate = GS.IDLE
            else:
                self._finish_with(m, S.E_AXIS_BLOCKED)
        elif m.kind == "snap":
            self.motion = None

    def _part_lost(self, t: float) -> None:
        """The part was removed while held: 41h PART_LOST, counted (42h), logged."""
        self.gstate = GS.PART_LOST
        self.stats[2] += 1
        self.log.add(t, LogLevel.WARNING, f"part lost at {self.traj.position(t):.2f} mm")

    def _stall(self, m: Motion) -> None:
        """26h blocked: the manual lists no blocked status for it, so the drive pushes on (RELEASING)
        and the command ends E_TIMEOUT at its deadline, or completes if the obstacle goes first."""
        m.stalled = True
        self.motion = m

    def _wrong_reference(self, t: float, m: Motion, x: float) -> None:
        """000 §3.2.1: "Obstacles … during homing may result in a wrong reference point": the blocking
        position (``x``, in the old coordinates) becomes the origin (0 mm homing negative, the stroke
        homing positive)."""
        origin = self.profile.stroke if m.direction > 0 else 0.0
        self.offset = x + self.offset - origin
        self.halt(t, origin)
        self.referenced = True
        self.gstate = GS.IDLE
        self.bits |= SF_TARGET_POS_REACHED
        self.log.add(t, LogLevel.WARNING, f"homing stopped by an obstacle {abs(self.offset):.2f} mm before the "
                                          "end stop: wrong reference point (000 §3.2.1), home again without it")
        self._finish_with(m, S.E_SUCCESS)

    def obstacles_changed(self, now: float) -> None:
        """An obstacle moved: release or lose what was held, snap a clamp whose obstacle went."""
        c = self.contact
        if c is not None and self.obstacles.get(c.obstacle.kind) is not c.obstacle:
            self.contact = None
            x = self.traj.position(now)
            self.bits &= ~SF_BLOCKED
            if c.kind == "hold":
                # The part monitor sees the gripping force go and stops the drive where the fingers are:
                # PART_LOST at rest, so the 21h/25h/26h that 000 §3.4.2 names follow at once
                # (docs/fidelity.md "A lost part")
                self.halt(now)
                self._part_lost(now)
            elif c.kind == "clamp":
                self.motion = Motion("snap", None, None, c.target, c.speed, c.direction)
                self.traj = plan_move(now, x, c.target, max(c.speed, self.profile.min_speed), self.acceleration)
            elif c.kind == "press" and c.resume is not None and self.motion is None:
                m = self.motion = c.resume
                v = max(m.speed, self.profile.min_speed)
                self.traj = (plan_velocity(now, x, 0.0, m.direction * v, self.acceleration) if m.velocity_mode
                             else plan_move(now, x, m.target, v, self.acceleration))
            elif c.kind == "stall" and self.motion is not None:  # the release goes on to its width
                self.motion.stalled = False
                self.traj = plan_move(now, x, c.target, max(c.speed, self.profile.min_speed), self.acceleration)
        elif self.motion is None and self.bits & SF_BLOCKED:
            self.bits &= ~SF_BLOCKED
        self.update_load(now)

    # ------------------------------------------------------------------ jog and script motion

    def jog_stop(self, now: float) -> bool:
        """End a jog (level back to 0): "the Jog mode is left and the drive is stopped" (002 §4.7,
        003 §5.7) — a running jog stops, a jog pressing on an obstacle lets go (force 0, BLOCKED flags
        cleared as by a stop, 000 App. B D2/D3). True if either was the case."""
        m = self.motion
        c = self.contact
        pressing = c is not None and c.kind == "press" and c.resume is None  # a jog's press (scripts resume)
        if (m is None or m.kind != "jog") and not pressing:
            return False
        if m is not None and m.kind == "jog":
            self.halt(now)
            self.motion = None
            self.gstate = GS.IDLE
        if pressing:
            self.contact = None
            self.bits &= ~SF_BLOCKED
        self.update_load(now)
        return True

    def jog(self, now: float, d: int, speed: float, force: float) -> bool:
        """Run at ``speed`` mm/s in direction ``d`` until an end stop, an obstacle (pressing with
        ``force`` N) or a soft limit; False if nothing had to change."""
        m = self.motion
        v = self.profile.clamp_speed(speed if speed > 0 else self.profile.min_speed)
        f = min(max(force, self.profile.min_force), self.max_force())
        if m is not None and m.kind == "jog" and m.direction == d and m.speed == v and m.force == f:
            return False  # level still held: nothing changes
        c = self.contact
        if m is None and c is not None and c.kind == "press" and c.direction == d:
            c.force = f  # still pressing against the same obstacle
            return True
        self.gstate = GS.POSITIONING
        target = self.profile.stroke if d > 0 else 0.0
        self.start(now, Motion("jog", None, None, target, v, d, force=f),
                   plan_velocity(now, self.traj.position(now), self.traj.velocity(now), d * v, self.acceleration))
        return True

    def script_move(self, now: float, width: float, speed: float) -> None:
        x = self.traj.position(now)
        target = min(max(width, 0.0), self.profile.stroke)
        v = self.profile.clamp_speed(abs(speed))
        d = 1 if target >= x else -1
        self.start(now, Motion("script", None, None, target, v, d, force=self.force_limit),
                   plan_move(now, x, target, v, self.acceleration, v0=self.traj.velocity(now)))

    def script_speed(self, now: float, velocity: float, force: float | None) -> bool:
        """Run at ``velocity`` mm/s (signed) until blocked; False if already pressing that way."""
        d = 1 if velocity > 0 else -1
        c = self.contact
        if c is not None and c.kind == "press" and c.direction == d:
            if force is not None:
                c.force = force
            return False  # still pressing against the same obstacle
        v = min(abs(velocity), self.profile.max_speed)
        target = self.profile.stroke if d > 0 else 0.0
        f = self.force_limit if force is None else force
        self.start(now, Motion("script", None, None, target, v, d, force=f, velocity_mode=True),
                   plan_velocity(now, self.traj.position(now), self.traj.velocity(now), d * v, self.acceleration))
        return True

    def script_halt(self, now: float) -> bool:
        """Speed 0: a script motion stops where it is; True if one ran."""
        if self.motion is not None and self.motion.kind == "script":
            self.halt(now)
            self.motion = None
            return True
        return False

    def script_stop(self, now: float) -> None:
        """The script lets go: motion stopped, pressing ended, BLOCKED flags cleared."""
        self.script_halt(now)
        if self.contact is not None and self.contact.kind == "press":
            self.contact = None
        self.bits &= ~SF_BLOCKED
        self.update_load(now)
