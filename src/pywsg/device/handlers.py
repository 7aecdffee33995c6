"""The firmware's command handlers: one small function per command ID of the catalog (000 §3.1–3.6).

Each handler gets the device, the client session, the request payload (its length already checked
against the catalog's request layout) and the clock time, and returns the immediate reply. Motions
answer E_CMD_PENDING here; their final reply comes from the axis when they end. :data:`HANDLERS` maps
every command ID to its handler, in the catalog's order — the one place to read what a command does.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Callable
from functools import partial

from ..protocol import CATALOG, Command, FingerType, Frame, GripperState, HomingDirection, PrepositionFlag, Status
from .axis import MOTION_TIMEOUT_S, POS_EPS, SF_AXIS_STOPPED, SF_BLOCKED, Motion
from .core import DeviceCore
from .fingers import POWER_UP_S
from .log import LogLevel
from .motion import Phase, Trajectory, plan_move
from .session import Session
from .streams import AUTO_UPDATE_IDS

S = Status
GS = GripperState

HOMING_STALL_S = 0.2  # s: the shortest homing, pushing into the end stop until the stall is seen

Handler = Callable[[DeviceCore, Session, bytes, float], Frame]

_U16 = struct.Struct("<H")
_F32 = struct.Struct("<f")
_PREPOS = CATALOG[Command.PREPOSITION].request_layout.struct
_GRIP = CATALOG[Command.GRIP_PART].request_layout.struct
_RELEASE = CATALOG[Command.RELEASE_PART].request_layout.struct
_SOFT = CATALOG[Command.SET_SOFT_LIMITS].request_layout.struct
_STATS = CATALOG[Command.GET_GRIPPING_STATISTICS].reply_layout.struct
_INFO = CATALOG[Command.GET_SYSTEM_INFO].reply_layout.struct
_LIMITS = CATALOG[Command.GET_SYSTEM_LIMITS].reply_layout.struct
_FINGER_INFO = CATALOG[Command.GET_FINGER1_INFO].reply_layout.struct
_TEMP = CATALOG[Command.GET_TEMPERATURE].reply_layout.struct

_MOVING_STATES = (GS.GRIPPING, GS.RELEASING, GS.POSITIONING)


# 3.1 connection management

def loop(g: DeviceCore, s: Session, payload: bytes, now: float) -> Frame:
    if len(payload) > 256:
        return Frame.reply(0x06, S.E_CMD_FORMAT_ERROR)
    if not payload:
        return Frame.reply(0x06, S.E_INVALID_PARAMETER)  # nothing to loop: "parameter value undefined"
    return Frame.reply(0x06, S.E_SUCCESS, payload)


def disconnect(g: DeviceCore, s: Session, payload: bytes, now: float) -> Frame:
    if not s.connection_oriented:
        return Frame.reply(0x07, S.E_NOT_AVAILABLE)
    s.announced = True
    s.subscriptions.clear()
    axis = g.axis
    if axis.motion is not None or axis.traj.is_moving(now):
        g.abort_motion(S.E_CMD_ABORTED, now)
        if axis.gstate in _MOVING_STATES:
            axis.gstate = GS.IDLE
    g.log.add(now, LogLevel.INFO, f"disconnect announced by {s.peer or s.kind}")
    g.changed()
    return Frame.reply(0x07, S.E_SUCCESS)


# 3.2 motion control

def _refused(g: DeviceCore, cid: int, width: float, speed: float, now: float) -> Frame | None:
    """The immediate errors 21h, 25h and 26h share: a NaN or infinite width or speed, then FAST STOP
    (E_ACCESS_DENIED), a motion running (E_ALREADY_RUNNING), not referenced (E_NOT_INITIALIZED)."""
    if not (math.isfinite(width) and math.isfinite(speed)):
        return Frame.reply(cid, S.E_INVALID_PARAMETER)
    denied = g.motion_denied(now)
    return None if denied is None else Frame.reply(cid, denied)


def homing(g: DeviceCore, s: Session, payload: bytes, now: float) -> Frame:
    denied = g.motion_denied(now, need_reference=False)
    if denied is not None:
        return Frame.reply(0x20, denied)
    direction = payload[0]
    if direction not in (0, 1, 2):
        return Frame.reply(0x20, S.E_INVALID_PARAMETER)
    if direction == HomingDirection.DEFAULT:
        direction = g.settings.homing_direction
    d = 1 if direction == HomingDirection.POSITIVE else -1
    g.script_stop_if_running(now)
    axis = g.axis
    target = (g.profile.stroke if d > 0 else 0.0) - axis.offset  # the mechanical end stop, where it really is
    x = axis.traj.position(now)
    axis.referenced = False
    axis.gstate = GS.POSITIONING
    traj = plan_move(now, x, target, g.profile.homing_speed, axis.acceleration)
    if traj.end_time - now < HOMING_STALL_S:
        # Already at (or next to) the end stop: the drive still pushes into it until it detects the
        # stall (000 §3.2.1), so homing is never instant and a PLC polling the image sees it run.
        traj = Trajectory([*traj.phases, Phase(traj.end_time, target, 0.0, 0.0, now + HOMING_STALL_S)], now, x)
    g.start_motion(now, Motion("homing", s, 0x20, target, g.profile.homing_speed, d), traj)
    g.log.add(now, LogLevel.INFO, f"homing in {'positive' if d > 0 else 'negative'} direction")
    return Frame.reply(0x20, S.E_CMD_PENDING)


def preposition(g: DeviceCore, s: Session, payload: bytes, now: float) -> Frame:
    flags, width, speed = _PREPOS.unpack(payload)
    refused = _refused(g, 0x21, width, speed, now)
    if refused is not None:
        return refused
    axis = g.axis
    x = axis.traj.position(now)
    target = x + width if flags & PrepositionFlag.RELATIVE else width
    target = min(max(target, 0.0), g.profile.stroke)  # outside the stroke: clamped
    if axis.soft_range_error(target):
        return Frame.reply(0x21, S.E_RANGE_ERROR)
    g.script_stop_if_running(now)
    v = g.profile.clamp_speed(speed)
    d = 1 if target >= x else -1
    axis.gstate = GS.POSITIONING  # leaving a held part: start_motion lets go of it (or meets it)
    g.start_motion(now, Motion("prepos", s, 0x21, target, v, d,
                               stop_on_block=bool(flags & PrepositionFlag.STOP_ON_BLOCK)),
                   plan_move(now, x, target, v, axis.acceleration))
    return Frame.reply(0x21, S.E_CMD_PENDING)


def stop(g: DeviceCore, s: Session, payload: bytes, now: float) -> Frame:
    axis = g.axis
    was = g.abort_motion(S.E_CMD_ABORTED, now)
    axis.bits |= SF_AXIS_STOPPED
    axis.bits &= ~SF_BLOCKED
    if was and axis.gstate in _MOVING_STATES:
        axis.gstate = GS.IDLE
    g.changed()
    return Frame.reply(0x22, S.E_SUCCESS)


def fast_stop(g: DeviceCore, s: Session, payload: bytes, now: float) -> Frame:
    # executed whatever the payload: an emergency stop must never be refused
    g.fast_stop(now, f"command 23h from {s.peer or s.kind}")
    return Frame.reply(0x23, S.E_SUCCESS)


def acknowledge(g: DeviceCore, s: Session, payload: bytes, now: float) -> Frame:
    if payload != b"ack":
        return Frame.reply(0x24, S.E_CMD_FORMAT_ERROR)
    return Frame.reply(0x24, g.acknowledge_fast_stop())


def grip(g: DeviceCore, s: Session, payload: bytes, now: float) -> Frame:
    width, speed = _GRIP.unpack(payload)
    refused = _refused(g, 0x25, width, speed, now)
    if refused is not None:
        return refused
    axis = g.axis
    if axis.soft_range_error(width):
        return Frame.reply(0x25, S.E_RANGE_ERROR)
    x = axis.traj.position(now)
    nominal = min(max(width, 0.0), g.profile.stroke)
    d = -1 if nominal < x else 1
    touching = axis.touching(x)
    if touching is not None and abs(nominal - x) <= POS_EPS:
        d = touching.blocks  # resting on the part (e.g. after a FAST STOP let go of it): grip into it
    c = axis.contact
    if c is not None and c.kind == "hold":
        if c.direction != d:
            return Frame.reply(0x25, S.E_ACCESS_DENIED)  # against the held part
        d = c.direction
    g.script_stop_if_running(now)
    target = min(max(nominal + d * g.settings.clamping_travel, 0.0), g.profile.stroke)
    v = g.profile.clamp_speed(speed)
    axis.gstate = GS.GRIPPING
    axis.stats[0] += 1
    if c is not None and c.kind == "hold":
        # re-grip in the same direction: lift off the part first (the part stays where it is)
        x = axis.local(c.obstacle.width) - d * 1e-6
    elif touching is not None and touching.blocks == d:
        x -= d * 1e-6  # start just off the surface so that the contact is seen
    g.start_motion(now, Motion("grip", s, 0x25, target, v, d, nominal=nominal),
                   plan_move(now, x, target, v, axis.acceleration))
    return Frame.reply(0x25, S.E_CMD_PENDING)


def release(g: DeviceCore, s: Session, payload: bytes, now: float) -> Frame:
    width, speed = _RELEASE.unpack(payload)
    refused = _refused(g, 0x26, width, speed, now)
    if refused is not None:
        return refused
    axis = g.axis
    target = min(max(width, 0.0), g.profile.stroke)
    if axis.soft_range_error(target):
        return Frame.reply(0x26, S.E_RANGE_ERROR)
    g.script_stop_if_running(now)
    x = axis.traj.position(now)
    v = g.profile.clamp_speed(speed)
    d = 1 if target >= x else -1
    axis.gstate = GS.RELEASING
    traj = plan_move(now, x, target, v, axis.acceleration)
    # 000 §3.2.7 lists E_TIMEOUT, not E_AXIS_BLOCKED: a blocked release pushes on until its deadline
    g.start_motion(now, Motion("release", s, 0x26, target, v, d, deadline=traj.end_time + MOTION_TIMEOUT_S), traj)
    return Frame.reply(0x26, S.E_CMD_PENDING)


# 3.3 motion configuration

def set_acceleration(g: DeviceCore, s: Session, payload: bytes, now: float) -> Frame:
    (acc,) = _F32.unpack(payload)
    if math.isnan(acc):
        return Frame.reply(0x30, S.E_INVALID_PARAMETER)
    g.axis.acceleration = g.profile.clamp_acc(acc)
    return Frame.reply(0x30, S.E_SUCCESS)


def get_acceleration(g: DeviceCore, s: Session, payload: bytes, now: float) -> Frame:
    return Frame.reply(0x31, S.E_SUCCESS, _F32.pack(g.axis.acceleration))


def set_force_limit(g: DeviceCore, s: Session, payload: bytes, now: float) -> Frame:
    (force,) = _F32.unpack(payload)
    if math.isnan(force):
        return Frame.reply(0x32, S.E_INVALID_PARAMETER)
    g.axis.force_limit = min(max(force, g.profile.min_force), g.axis.max_force())
    return Frame.reply(0x32, S.E_SUCCESS)


def get_force_limit(g: DeviceCore, s: Session, payload: bytes, now: float) -> Frame:
    return Frame.reply(0x33, S.E_SUCCESS, _F32.pack(g.axis.force_limit))


def set_soft_limits(g: DeviceCore, s: Session, payload: bytes, now: float) -> Frame:
    minus, plus = _SOFT.unpack(payload)
    if not (math.isfinite(minus) and math.isfinite(plus)) or minus > plus:
        return Frame.reply(0x34, S.E_INVALID_PARAMETER)
    # kept as given: 35h "Return the soft limits if set" (000 §3.3.6); beyond the stroke they never bite
    g.axis.soft_limits = (minus, plus)
    g.log.add(now, LogLevel.INFO, f"soft limits set: {minus:.2f} .. {plus:.2f} mm")
    g.reschedule(now)
    g.changed()
    return Frame.reply(0x34, S.E_SUCCESS)


def get_soft_limits(g: DeviceCore, s: Session, payload: bytes, now: float) -> Frame:
    if g.axis.soft_limits is None:
        return Frame.reply(0x35, S.E_NOT_AVAILABLE)
    return Frame.reply(0x35, S.E_SUCCESS, _SOFT.pack(*g.axis.soft_limits))


def clear_soft_limits(g: DeviceCore, s: Session, payload: bytes, now: float) -> Frame:
    if g.axis.soft_limits is not None:
        g.axis.soft_limits = None
        g.log.add(now, LogLevel.INFO, "soft limits cleared")
        g.reschedule(now)
        g.changed()
    return Frame.reply(0x36, S.E_SUCCESS)


def overdrive(g: DeviceCore, s: Session, payload: bytes, now: float) -> Frame:
    on = bool(payload[0] & 1)
    if payload[0] & 0xFE:
        return Frame.reply(0x37, S.E_INVALID_PARAMETER)
    axis = g.axis
    if on != axis.overdrive:
        axis.overdrive = on
        g.log.add(now, LogLevel.WARNING if on else LogLevel.INFO,
                  "overdrive mode entered" if on else "overdrive mode left")
        if not on and axis.force_limit > g.profile.nom_force:
            axis.force_limit = g.profile.nom_force
            if axis.contact is not None and axis.contact.kind == "hold":
                axis.contact.force = axis.force_limit
                axis.update_load(now)
                g.reschedule(now)
        g.changed()
    return Frame.reply(0x37, S.E_SUCCESS)


def tare(g: DeviceCore, s: Session, payload: bytes, now: float) -> Frame:
    fmf = [f for f in g.fingers if f.type == FingerType.WSG_FMF]
    if not fmf:
        return Frame.reply(0x38, S.E_NOT_AVAILABLE)
    if g.axis.gstate == GS.HOLDING:
        return Frame.reply(0x38, S.E_ACCESS_DENIED)
    force = g.force(now)
    for f in fmf:
        f.tare_offset = f.fmf_force(force) + f.tare_offset - force
    g.log.add(now, LogLevel.INFO, "force sensor tared")
    return Frame.reply(0x38, S.E_SUCCESS)


# 3.4 system state (40h, 41h, 43h–45h: auto-update values, see streams.Streams.request)

def auto_update(g: DeviceCore, s: Session, payload: bytes, now: float, cid: int) -> Frame:
    return g.streams.request(s, payload, now, cid)


def statistics(g: DeviceCore, s: Session, payload: bytes, now: float) -> Frame:
    flags = payload[0]
    stats = g.axis.stats
    t, n, lost = stats
    reply = Frame.reply(0x42, S.E_SUCCESS, _STATS.pack(t & 0xFFFFFFFF, min(n, 0xFFFF), min(lost, 0xFFFF)))
    if flags & 1:
        stats[:] = [0, 0, 0]
        g.log.add(now, LogLevel.INFO, "gripping statistics reset")
    return reply


def temperature(g: DeviceCore, s: Session, payload: bytes, now: float) -> Frame:
    return Frame.reply(0x46, S.E_SUCCESS, _TEMP.pack(max(-32768, min(32767, round(g.thermal.temperature(now) * 10)))))


# 3.5 system configuration

def system_info(g: DeviceCore, s: Session, payload: bytes, now: float) -> Frame:
    p = g.profile
    return Frame.reply(0x50, S.E_SUCCESS, _INFO.pack(int(p.device_type), p.hwrev, p.fw_version, g.serial_number))


def set_tag(g: DeviceCore, s: Session, payload: bytes, now: float) -> Frame:
    if len(payload) > 64:
        return Frame.reply(0x51, S.E_OVERRUN)
    if not payload or any(b < 0x20 or b > 0x7E for b in payload):
        return Frame.reply(0x51, S.E_INVALID_PARAMETER)
    g.tag = payload.decode("ascii")
    g.settings = g.settings.updated(tag=g.tag)  # saved with the settings: the tag survives a restart
    return Frame.reply(0x51, S.E_SUCCESS)


def get_tag(g: DeviceCore, s: Session, payload: bytes, now: float) -> Frame:
    if g.tag is None:
        return Frame.reply(0x52, S.E_NOT_AVAILABLE)
    return Frame.reply(0x52, S.E_SUCCESS, g.tag.encode("ascii"))


def system_limits(g: DeviceCore, s: Session, payload: bytes, now: float) -> Frame:
    p = g.profile
    return Frame.reply(0x53, S.E_SUCCESS, _LIMITS.pack(p.stroke, p.min_speed, p.max_speed, p.min_acc,
                                                       p.max_acc, p.min_force, p.nom_force, p.ovr_force))


# 3.6 finger interface (finger 1: 60h–63h, finger 2: 70h–73h)

def finger_info(g: DeviceCore, s: Session, payload: bytes, now: float, n: int, cid: int) -> Frame:
    f = g.fingers[n]
    return Frame.reply(cid, S.E_SUCCESS, _FINGER_INFO.pack(int(f.type), f.frame_size))


def finger_flags(g: DeviceCore, s: Session, payload: bytes, now: float, n: int, cid: int) -> Frame:
    return Frame.reply(cid, S.E_SUCCESS, _U16.pack(int(g.fingers[n].flags())))


def finger_power(g: DeviceCore, s: Session, payload: bytes, now: float, n: int, cid: int) -> Frame:
    f = g.fingers[n]
    on = payload[0]
    if on not in (0, 1):
        return Frame.reply(cid, S.E_INVALID_PARAMETER)
    if f.type != FingerType.GENERIC:
        return Frame.reply(cid, S.E_ACCESS_DENIED)  # predefined fingers are not switchable
    if not on:
        f.powered = False
        f.powering_until = None
        g.changed()
        return Frame.reply(cid, S.E_SUCCESS)
    if f.fault:
        return Frame.reply(cid, S.E_CMD_FAILED)  # over-current while enabling
    if f.powering_until is not None:
        return Frame.reply(cid, S.E_ALREADY_RUNNING)
    f.powered = False
    f.powering_until = now + POWER_UP_S
    g.add_timer(now + POWER_UP_S, "finger_power", n, s, cid)
    g.changed()
    return Frame.reply(cid, S.E_CMD_PENDING)


def finger_data(g: DeviceCore, s: Session, payload: bytes, now: float, n: int, cid: int) -> Frame:
    f = g.fingers[n]
    if f.type == FingerType.GENERIC:
        return Frame.reply(cid, S.E_NOT_AVAILABLE)
    if f.fault or f.comm_fault or not f.powered:
        return Frame.reply(cid, S.E_IO_ERROR)
    return Frame.reply(cid, S.E_SUCCESS, f.data(g.force(now), g.axis.holding()))


def _table() -> dict[int, Handler]:
    h: dict[int, Handler] = {
        0x06: loop, 0x07: disconnect,
        0x20: homing, 0x21: preposition, 0x22: stop, 0x23: fast_stop, 0x24: acknowledge, 0x25: grip,
        0x26: release,
        0x30: set_acceleration, 0x31: get_acceleration, 0x32: set_force_limit, 0x33: get_force_limit,
        0x34: set_soft_limits, 0x35: get_soft_limits, 0x36: clear_soft_limits, 0x37: overdrive, 0x38: tare,
        0x42: statistics, 0x46: temperature,
        0x50: system_info, 0x51: set_tag, 0x52: get_tag, 0x53: system_limits,
    }
    for cid in AUTO_UPDATE_IDS:
        h[cid] = partial(auto_update, cid=int(cid))
    for n, base in ((0, 0x60), (1, 0x70)):
        h[base] = partial(finger_info, n=n, cid=base)
        h[base + 1] = partial(finger_flags, n=n, cid=base + 1)
        h[base + 2] = partial(finger_power, n=n, cid=base + 2)
        h[base + 3] = partial(finger_data, n=n, cid=base + 3)
    return dict(sorted(h.items()))


HANDLERS: dict[int, Handler] = _table()
"""Command ID → handler, for every command of the catalog."""


def request_size(cid: int) -> int | None:
    """The fixed request payload size of ``cid`` (None: variable, the handler checks it)."""
    layout = CATALOG[cid].request_layout
    return None if layout.variable is not None else layout.fixed_size


def length_error(cid: int) -> Status:
    """The status for a request payload of the wrong length: the command's own list decides.

    A payload given to a command without parameters is E_NO_PARAM_EXPECTED where the manual lists it
    (e.g. 31h, 000 §3.3.2); the finger commands 60h–63h / 70h–73h list only E_CMD_FORMAT_ERROR
    ("Command length mismatch", 000 §3.6.1–3.6.8), so they answer that.
    """
    spec = CATALOG[cid]
    if request_size(cid) == 0 and S.E_NO_PARAM_EXPECTED in spec.statuses:
        return S.E_NO_PARAM_EXPECTED
    return S.E_CMD_FORMAT_ERROR
