"""The virtual gripper: model (closed-form motion on an injected clock) plus firmware (frames in,
frames out), sans-IO.

Requests come in through :meth:`VirtualGripper.feed` / :meth:`handle_frame` /
:meth:`handle_datagram` and are answered at once; everything that happens later (final replies of
motions, auto-update packets, finger power-up) is collected by :meth:`poll`, and
:meth:`next_due` says when to call it next. Nothing here sleeps or touches a socket.
"""

from __future__ import annotations

import heapq
import math
import struct
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import partial
from typing import TYPE_CHECKING

from ..protocol import (
    CATALOG,
    MAX_PAYLOAD,
    AutoUpdateFlag,
    ChecksumMismatch,
    Command,
    FingerType,
    Frame,
    FrameParser,
    FrameTooLarge,
    GripperState,
    HomingDirection,
    ParseError,
    PrepositionFlag,
    Status,
    SystemFlag,
    Truncated,
    parse_datagram,
)
from .clock import Clock, monotonic_clock
from .faults import Faults, Obstacle
from .fingers import POWER_UP_S, Finger
from .log import LogLevel, SystemLog
from .motion import Trajectory, plan_move, plan_velocity
from .profiles import Profile, get_profile
from .session import Deliver, Session, Subscription
from .settings import Settings
from .thermal import FAULT_C, WARNING_C, ThermalModel

if TYPE_CHECKING:
    from .plugins import FirmwarePlugin

S = Status
GS = GripperState

_U8 = struct.Struct("<B")
_U16 = struct.Struct("<H")
_U32 = struct.Struct("<I")
_F32 = struct.Struct("<f")
_AUTO = CATALOG[Command.GET_SYSTEM_STATE].request_layout.struct  # FLAGS u8, PERIOD_MS u16
_PREPOS = CATALOG[Command.PREPOSITION].request_layout.struct
_GRIP = CATALOG[Command.GRIP_PART].request_layout.struct
_RELEASE = CATALOG[Command.RELEASE_PART].request_layout.struct
_SOFT = CATALOG[Command.SET_SOFT_LIMITS].request_layout.struct
_STATS = CATALOG[Command.GET_GRIPPING_STATISTICS].reply_layout.struct
_INFO = CATALOG[Command.GET_SYSTEM_INFO].reply_layout.struct
_LIMITS = CATALOG[Command.GET_SYSTEM_LIMITS].reply_layout.struct
_FINGER_INFO = CATALOG[Command.GET_FINGER1_INFO].reply_layout.struct
_TEMP = CATALOG[Command.GET_TEMPERATURE].reply_layout.struct

_SF_AXIS_STOPPED = int(SystemFlag.SF_AXIS_STOPPED)
_SF_BLOCKED_MINUS = int(SystemFlag.SF_BLOCKED_MINUS)
_SF_BLOCKED_PLUS = int(SystemFlag.SF_BLOCKED_PLUS)
_SF_CMD_FAILURE = int(SystemFlag.SF_CMD_FAILURE)
_SF_CURR_FAULT = int(SystemFlag.SF_CURR_FAULT)
_SF_FAST_STOP = int(SystemFlag.SF_FAST_STOP)
_SF_FINGER_FAULT = int(SystemFlag.SF_FINGER_FAULT)
_SF_FORCECNTL_MODE = int(SystemFlag.SF_FORCECNTL_MODE)
_SF_MOVING = int(SystemFlag.SF_MOVING)
_SF_OVERDRIVE_MODE = int(SystemFlag.SF_OVERDRIVE_MODE)
_SF_POWER_FAULT = int(SystemFlag.SF_POWER_FAULT)
_SF_REFERENCED = int(SystemFlag.SF_REFERENCED)
_SF_SCRIPT_FAILURE = int(SystemFlag.SF_SCRIPT_FAILURE)
_SF_SCRIPT_RUNNING = int(SystemFlag.SF_SCRIPT_RUNNING)
_SF_SOFT_LIMIT_MINUS = int(SystemFlag.SF_SOFT_LIMIT_MINUS)
_SF_SOFT_LIMIT_PLUS = int(SystemFlag.SF_SOFT_LIMIT_PLUS)
_SF_TARGET_POS_REACHED = int(SystemFlag.SF_TARGET_POS_REACHED)
_SF_TEMP_FAULT = int(SystemFlag.SF_TEMP_FAULT)
_SF_TEMP_WARNING = int(SystemFlag.SF_TEMP_WARNING)

_AUTO_UPDATE = int(AutoUpdateFlag.AUTO_UPDATE)
_CHANGE_ONLY = int(AutoUpdateFlag.CHANGE_ONLY)
SOFT_EPS = 1e-6  # mm: a soft limit is violated only strictly beyond it
POS_EPS = 1e-6
SPEED_EPS = 1e-6
MIN_PERIOD_MS = 10
CHANGE_THRESHOLDS: dict[int, float] = {  # the manual's change thresholds for change-only updates
    Command.GET_OPENING_WIDTH: 0.01,  # mm
    Command.GET_SPEED: 0.05,  # mm/s
    Command.GET_FORCE: 0.05,  # N
}
AUTO_UPDATE_IDS = frozenset((Command.GET_SYSTEM_STATE, Command.GET_GRIPPER_STATE, Command.GET_OPENING_WIDTH,
                             Command.GET_SPEED, Command.GET_FORCE))
# commands whose success does not clear SF_CMD_FAILURE ("the last command returned an error"):
# read-only queries would otherwise always clear it before it could be read.
QUERY_IDS = frozenset((0x06, 0x31, 0x33, 0x35, 0x40, 0x41, 0x42, 0x43, 0x44, 0x45, 0x46, 0x50, 0x52, 0x53,
                       0x60, 0x61, 0x63, 0x70, 0x71, 0x73))
MOTION_IDS = frozenset((0x20, 0x21, 0x25, 0x26))
# plain ints for the hot paths (comparing with an IntEnum member looks it up on the class each time)
_ID_SYSTEM_STATE = int(Command.GET_SYSTEM_STATE)
_ID_GRIPPER_STATE = int(Command.GET_GRIPPER_STATE)
_ID_WIDTH = int(Command.GET_OPENING_WIDTH)
_ID_SPEED = int(Command.GET_SPEED)
_OK = b"\x00\x00"  # E_SUCCESS status bytes
_E_CMD_PENDING = int(Status.E_CMD_PENDING)
_REQUEST_CACHE_SIZE = 256
_REQUEST_CACHE_BYTES = 64
DEFAULT_STIFFNESS = 500.0  # N/mm, assumed part stiffness


@dataclass(slots=True)
class Motion:
    """The motion in progress and what to answer when it ends.

    ``kind``: homing, prepos, grip, release, jog, script, lost (part lost: fingers run on to the
    end of the clamping travel), snap (obstacle removed while clamping).
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


@dataclass(slots=True)
class Contact:
    """Fingers resting on an obstacle: holding a part, clamping (21h), or pressing (jog/script)."""

    obstacle: Obstacle
    direction: int  # direction the fingers push in
    force: float  # N
    kind: str  # hold, clamp, press, blocked
    target: float = 0.0  # clamp: where to snap when the obstacle goes
    speed: float = 0.0
    nominal: float = 0.0


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


def _max_request(command_id: int) -> int:
    spec = CATALOG.get(command_id)
    if spec is None:
        return MAX_PAYLOAD
    size = spec.max_request_size
    # let a stray payload to a no-parameter command through, to answer E_NO_PARAM_EXPECTED
    return size if size else 64


# the parser asks for every frame: one table lookup instead of a catalog walk
_MAX_REQUEST: tuple[int, ...] = tuple(_max_request(i) for i in range(256))


class VirtualGripper:
    """A WSG that answers every command of the command manual like the real one.

    ``model``: profile key (None: ``settings.model``); ``clock``: seconds, defaults to
    :func:`time.monotonic` (tests pass a :class:`~pywsg.device.ManualClock`).
    """

    def __init__(self, model: str | None = None, settings: Settings | None = None,
                 clock: Clock | None = None) -> None:
        settings = settings or Settings()
        if model is not None:
            settings = settings.updated(model=get_profile(model).key)
        self.clock: Clock = clock or monotonic_clock
        self.log = SystemLog()
        self.faults = Faults(self)
        self._listeners: list[Callable[[], None]] = []
        self._sessions: list[Session] = []
        self._tcp_holder: Session | None = None
        self._outbox: list[tuple[Session, Frame]] = []
        self._timers: list[tuple[float, int, str, tuple[object, ...]]] = []
        self._timer_seq = 0
        self.plugins: dict[str, FirmwarePlugin] = {}
        self._plugin_cmds: dict[int, FirmwarePlugin] = {}
        self._dispatch = self._build_dispatch()
        # requests seen before, as their exact bytes (a polling client repeats them): parsed once.
        # Only frames with a valid checksum go in, so a hit is right whatever the CRC setting.
        self._requests: dict[bytes, Frame] = {}
        self._value_frames: dict[int, Frame] = {}  # last value frame per ID (values repeat at rest)
        self.settings = settings
        self._power_up(settings)

    # ------------------------------------------------------------------ power-up / settings

    def _power_up(self, settings: Settings) -> None:
        """(Re)start the device: session values back to their defaults, not referenced."""
        now = self.clock()
        self.profile: Profile = get_profile(settings.model)
        p = self.profile
        self.settings = settings
        self.serial_number = settings.serial_number if settings.serial_number is not None else p.serial_number
        self.acceleration = p.clamp_acc(settings.acceleration)
        self.force_limit = min(max(settings.force_limit, p.min_force), p.nom_force)
        self.soft_limits: tuple[float, float] | None = None
        self.overdrive = False
        self.referenced = False
        self.gstate = GS.IDLE
        self._traj = Trajectory.rest(now, p.stroke / 2)  # unknown position until homing
        self._motion: Motion | None = None
        self._contact: Contact | None = None
        self._event: tuple[float, int, str, object] | None = None
        self._bits = 0  # latched flags: FAST_STOP, AXIS_STOPPED, TARGET_POS_REACHED, CMD_FAILURE, ...
        self.obstacles: dict[str, Obstacle] = {}
        self.stats = [0, 0, 0]
        self.tag: str | None = None
        self.fingers = [Finger.of(settings.finger1), Finger.of(settings.finger2)]
        self.thermal = ThermalModel(now)
        self.power_fault = False
        self.current_fault = False
        self.script_if = 0
        self.script_of = 0
        self.script_failure = False
        self._temp_state = 0  # 0 normal, 1 warning, 2 fault
        self._version = 0
        self._next_event = math.inf
        self._due_valid = False
        self._due_cache: float | None = None
        for name in list(self.plugins):
            self.unload_plugin(name)
        if settings.script:
            self.load_plugin(settings.script)
        self.log.add(now, LogLevel.INFO, f"{p.name} started (firmware {_fw(p.fw_version)}, SN {self.serial_number})")
        self._changed()
        if settings.auto_homing:
            self._auto_home()

    def _auto_home(self) -> None:
        """Auto-homing at power-up: an ordinary 20h from an internal session, so every rule holds."""
        startup = next((s for s in self._sessions if s.kind == "startup"), None)
        if startup is None:
            startup = self.open_session("startup", peer="auto-homing")
        self.log.add(self.clock(), LogLevel.INFO, "auto-homing at start")
        self.handle_frame(startup, Frame(Command.HOMING, b"\x00"))

    def apply_settings(self, settings: Settings) -> None:
        """Take new settings. Raises ValueError naming the field if invalid.

        Changing ``model`` or the fingers restarts the virtual device (as a real one would be
        power-cycled after such a change): session values reset, homing needed again.
        """
        settings.validate()
        old = self.settings
        restart = (settings.model != old.model or settings.finger1 != old.finger1
                   or settings.finger2 != old.finger2 or settings.serial_number != old.serial_number)
        if restart:
            self._abort_motion(S.E_CMD_ABORTED, self.clock())
            self._power_up(settings)
        else:
            self.settings = settings
            if settings.script != old.script:
                for name in list(self.plugins):
                    self.unload_plugin(name)
                if settings.script:
                    self.load_plugin(settings.script)
        for s in self._sessions:
            s.parser.verify_checksum = settings.crc_check
        self.log.add(self.clock(), LogLevel.INFO, "settings changed")
        self._changed()

    def restart(self) -> None:
        """Power-cycle: session values (acceleration, force limit, soft limits, tag) are lost."""
        now = self.clock()
        self._abort_motion(S.E_CMD_ABORTED, now)
        self._power_up(self.settings)

    # ------------------------------------------------------------------ sessions

    def open_session(self, kind: str = "tcp", peer: str = "", deliver: Deliver | None = None) -> Session:
        """A new client session. Only one TCP client holds the command interface at a time; a second
        one is served but every command gets E_ACCESS_DENIED."""
        s = Session(kind, peer, deliver)
        s.parser = FrameParser(self.settings.crc_check, self._max_payload)
        if kind == "tcp":
            if self._tcp_holder is not None and not self._tcp_holder.closed:
                s.denied = True
                self.log.add(self.clock(), LogLevel.WARNING,
                             f"second TCP client {peer} refused: command interface in use")
            else:
                self._tcp_holder = s
        self._sessions.append(s)
        return s

    def close_session(self, s: Session) -> None:
        """The client went away. An unannounced TCP close raises FAST STOP (setting)."""
        if s.closed:
            return
        now = self.clock()
        self._advance(now)
        s.closed = True
        s.subscriptions.clear()
        if s in self._sessions:
            self._sessions.remove(s)
        self._outbox = [(x, f) for x, f in self._outbox if x is not s]
        if self._tcp_holder is s:
            self._tcp_holder = None
            if not s.announced and self.settings.fast_stop_on_disconnect:
                self._fast_stop(now, "unannounced disconnect of TCP client " + (s.peer or "?"))
        self._changed()

    @property
    def sessions(self) -> list[Session]:
        return list(self._sessions)

    def add_wakeup_listener(self, fn: Callable[[], None]) -> None:
        """``fn()`` is called whenever :meth:`next_due` may have moved earlier."""
        self._listeners.append(fn)

    def remove_wakeup_listener(self, fn: Callable[[], None]) -> None:
        if fn in self._listeners:
            self._listeners.remove(fn)

    # ------------------------------------------------------------------ byte / frame entry points

    def _max_payload(self, command_id: int) -> int:
        return _MAX_REQUEST[command_id]

    def _remember(self, data: bytes, frame: Frame) -> None:
        """``data`` is exactly ``frame`` with a valid checksum: parse it from the cache next time."""
        if len(data) <= _REQUEST_CACHE_BYTES and type(data) is bytes:
            if len(self._requests) >= _REQUEST_CACHE_SIZE:
                self._requests.clear()
            self._requests[data] = frame

    def feed(self, s: Session, data: bytes) -> list[Frame]:
        """Stream bytes from a client; returns the immediate replies in order."""
        parser = s.parser
        if type(data) is bytes and not parser.buffered:
            cached = self._requests.get(data)
            if cached is not None:  # exactly one frame read before (what the parser would return)
                return self.handle_frame(s, cached)
        events = parser.feed(data)
        if (len(events) == 1 and parser.verify_checksum and not parser.buffered
                and type(events[0]) is Frame and len(data) == len(events[0].payload) + 8):
            self._remember(data, events[0])
        return self._answer_events(s, events)

    def handle_datagram(self, s: Session, data: bytes) -> list[Frame]:
        """One UDP datagram holds one frame."""
        cached = self._requests.get(data) if type(data) is bytes else None
        if cached is not None:
            return self.handle_frame(s, cached)
        events = parse_datagram(data, self.settings.crc_check, self._max_payload)
        if len(events) == 1 and self.settings.crc_check and type(events[0]) is Frame:
            self._remember(data, events[0])
        return self._answer_events(s, events)

    def _answer_events(self, s: Session, events: list[Frame | ParseError]) -> list[Frame]:
        """Replies to parser output: frames are executed, parse errors answered with their status
        (bad CRC: E_CHECKSUM_ERROR; SIZE too large or a truncated datagram: E_CMD_FORMAT_ERROR, or
        E_CMD_UNKNOWN for an unknown ID); skipped garbage gets no answer."""
        out: list[Frame] = []
        for ev in events:
            if isinstance(ev, Frame):
                out.extend(self.handle_frame(s, ev))
            elif isinstance(ev, ChecksumMismatch):
                out.extend(self._answer_status(s, ev.command_id, S.E_CHECKSUM_ERROR))
            elif isinstance(ev, FrameTooLarge):
                known = ev.command_id in CATALOG or ev.command_id in self._plugin_cmds
                out.extend(self._answer_status(s, ev.command_id,
                                               S.E_CMD_FORMAT_ERROR if known else S.E_CMD_UNKNOWN))
            elif isinstance(ev, Truncated) and ev.command_id is not None:
                out.extend(self._answer_status(s, ev.command_id, S.E_CMD_FORMAT_ERROR))
        return out

    def _answer_status(self, s: Session, command_id: int, status: Status) -> list[Frame]:
        now = self.clock()
        self._advance(now)
        out = self._take_outbox(s) if self._outbox else []
        if s.denied or s.announced:
            status = S.E_ACCESS_DENIED
        self._bits |= _SF_CMD_FAILURE
        out.append(Frame.reply(command_id, status))
        self._changed()
        return out

    def handle_frame(self, s: Session, frame: Frame) -> list[Frame]:
        """Execute one request; returns the immediate replies (deferred ones come from :meth:`poll`)."""
        now = self.clock()
        if now >= self._next_event:
            self._advance(now)
        out = self._take_outbox(s) if self._outbox else []
        cid = frame.command_id
        payload = frame.payload
        if s.denied or s.announced or s.closed:
            reply = Frame.reply(cid, S.E_ACCESS_DENIED)
        else:
            entry = self._dispatch.get(cid)
            if entry is None:
                plugin = self._plugin_cmds.get(cid)
                if plugin is None:
                    reply = Frame.reply(cid, S.E_CMD_UNKNOWN)
                else:
                    reply = plugin.handle(self, s, cid, payload, now)
            else:
                handler, size = entry
                if size is not None and len(payload) != size and cid != Command.FAST_STOP:
                    reply = Frame.reply(cid, S.E_NO_PARAM_EXPECTED if size == 0 else S.E_CMD_FORMAT_ERROR)
                else:
                    reply = handler(s, payload, now)
        if self._outbox:
            out.extend(self._take_outbox(s))
        out.append(reply)
        p = reply.payload
        code = p[0] | (p[1] << 8)
        if code != 0 and code != _E_CMD_PENDING:
            if not self._bits & _SF_CMD_FAILURE:
                self._bits |= _SF_CMD_FAILURE
                self._changed()
        elif cid not in QUERY_IDS and self._bits & _SF_CMD_FAILURE:
            self._bits &= ~_SF_CMD_FAILURE
            self._changed()
        if not self._due_valid:
            self._notify()
        return out

    def _take_outbox(self, s: Session) -> list[Frame]:
        mine = [f for x, f in self._outbox if x is s]
        if mine:
            self._outbox = [(x, f) for x, f in self._outbox if x is not s]
        return mine

    # ------------------------------------------------------------------ time: poll / next_due

    def poll(self) -> list[tuple[Session, Frame]]:
        """Everything due at ``clock()``: final replies, auto-updates, power-up completions.

        Each frame is also passed to its session's ``deliver`` callback, if set. Cheap when
        nothing is due.
        """
        now = self.clock()
        if self._due_valid and (self._due_cache is None or now < self._due_cache):
            return []
        self._advance(now)
        self._run_subscriptions(now)
        due = self._outbox
        self._outbox = []
        for s, f in due:
            if s.deliver is not None and not s.closed:
                s.deliver(f)
        self._due_valid = False
        return due

    def next_due(self) -> float | None:
        """Clock time of the next event (final reply, auto-update, power-up, temperature threshold)."""
        if self._due_valid:
            return self._due_cache
        now = self.clock()
        due = self._next_event if self._next_event != math.inf else None
        if self._outbox:
            due = now if due is None else min(due, now)
        moving = self._traj.is_moving(now)
        for s in self._sessions:
            for sub in s.subscriptions.values():
                if not sub.change_only or moving or sub.checked_version != self._version:
                    t = sub.next_time
                    due = t if due is None or t < due else due
        self._due_cache = due
        self._due_valid = True
        return due

    def _changed(self) -> None:
        """State changed: change-only subscribers must look, and the due time may move."""
        self._version += 1
        self._due_valid = False

    def _notify(self) -> None:
        for fn in list(self._listeners):
            fn()

    def _reschedule(self, now: float) -> None:
        """Recompute the next internal event (motion, timer, temperature threshold)."""
        t = math.inf
        self._event = self._motion_event(now)
        if self._event is not None:
            t = self._event[0]
        if self._timers:
            t = min(t, self._timers[0][0])
        for th in (WARNING_C, FAULT_C):
            c = self.thermal.crossing(th, now)
            if c is not None and c < t:
                t = c
        self._next_event = t
        self._due_valid = False

    def _advance(self, now: float) -> None:
        """Process every internal event up to ``now``, in time order."""
        guard = 0
        while self._next_event <= now:
            guard += 1
            if guard > 10000:  # pragma: no cover - defensive
                raise RuntimeError("event loop does not converge")
            t = self._next_event
            if self._event is not None and self._event[0] <= t:
                ev = self._event
                self._event = None
                self._on_motion_event(ev[0], ev[2], ev[3])
            elif self._timers and self._timers[0][0] <= t:
                _, _, kind, args = heapq.heappop(self._timers)
                self._on_timer(t, kind, args)
            else:
                self._on_temperature(t)
            self._reschedule(t)
        self._update_temp_flags(now)

    def _schedule(self, t: float, kind: str, *args: object) -> None:
        self._timer_seq += 1
        heapq.heappush(self._timers, (t, self._timer_seq, kind, args))
        self._reschedule(self.clock())

    def _emit(self, s: Session | None, frame: Frame) -> None:
        if s is not None and not s.closed:
            self._outbox.append((s, frame))
            self._due_valid = False

    # ------------------------------------------------------------------ auto-update

    def _value_for(self, cid: int, now: float) -> float | int:
        if cid == _ID_WIDTH:
            return self.width(now)
        if cid == _ID_SYSTEM_STATE:
            return self._flag_bits(now)
        if cid == _ID_GRIPPER_STATE:
            return int(self.gstate)
        if cid == _ID_SPEED:
            return self.speed(now)
        return self.force(now)

    def _value_frame(self, cid: int, value: float | int) -> Frame:
        if cid == _ID_SYSTEM_STATE:
            payload = _OK + _U32.pack(int(value))
        elif cid == _ID_GRIPPER_STATE:
            payload = _OK + _U8.pack(int(value))
        else:
            payload = _OK + _F32.pack(float(value))
        last = self._value_frames.get(cid)
        if last is not None and last.payload == payload:
            return last  # frames are immutable: the same bytes, one object (and one cached encoding)
        frame = self._value_frames[cid] = Frame(cid, payload)
        return frame

    def _run_subscriptions(self, now: float) -> None:
        moving = self._traj.is_moving(now)
        version = self._version
        outbox = self._outbox
        value_for = self._value_for
        value_frame = self._value_frame
        for s in self._sessions:
            subs = s.subscriptions
            if not subs:
                continue
            for sub in subs.values():
                if now < sub.next_time:
                    continue
                cid = sub.command_id
                if sub.change_only:
                    if not moving and sub.checked_version == version:
                        continue
                    sub.checked_version = version
                    value = value_for(cid, now)
                    if not _changed(cid, sub.last_value, value):
                        continue
                else:
                    value = value_for(cid, now)
                sub.last_value = value
                outbox.append((s, value_frame(cid, value)))
                # keep the cadence, but never burst to catch up after a late poll
                nxt = sub.next_time + sub.period
                sub.next_time = nxt if nxt > now else now + sub.period

    def _auto_update(self, s: Session, payload: bytes, now: float, cid: int) -> Frame:
        flags, period_ms = _AUTO.unpack(payload)
        value = self._value_for(cid, now)
        if flags & _AUTO_UPDATE:
            if period_ms < MIN_PERIOD_MS:
                return Frame.reply(cid, S.E_INVALID_PARAMETER)
            period = period_ms / 1000.0
            s.subscriptions[cid] = Subscription(cid, period, bool(flags & _CHANGE_ONLY),
                                                now + period, value, self._version)
            self._due_valid = False
        elif s.subscriptions:
            s.subscriptions.pop(cid, None)
        return self._value_frame(cid, value)

    # ------------------------------------------------------------------ readings (closed form)

    def width(self, now: float | None = None) -> float:
        """Opening width in mm (0 when not referenced, as the manual says)."""
        if not self.referenced:
            return 0.0
        return self._traj.position(self.clock() if now is None else now)

    def true_width(self, now: float | None = None) -> float:
        """The physical width in mm, referenced or not."""
        return self._traj.position(self.clock() if now is None else now)

    def speed(self, now: float | None = None) -> float:
        """Finger speed in mm/s (rate of change of the opening width; negative when closing)."""
        return self._traj.velocity(self.clock() if now is None else now)

    def force(self, now: float | None = None) -> float:
        """Gripping force in N: the force limit while holding, 50 % nominal while clamping, else 0."""
        c = self._contact
        return c.force if c is not None else 0.0

    def temperature(self, now: float | None = None) -> float:
        return self.thermal.temperature(self.clock() if now is None else now)

    def moving(self, now: float | None = None) -> bool:
        return self._traj.is_moving(self.clock() if now is None else now)

    def system_flags(self, now: float | None = None) -> SystemFlag:
        """The 40h system state flags (Appendix B) at ``now``."""
        return SystemFlag(self._flag_bits(self.clock() if now is None else now))

    def _flag_bits(self, now: float) -> int:
        f = self._bits
        if self.referenced:
            f |= _SF_REFERENCED
            if self.soft_limits is not None:
                x = self._traj.position(now)
                if x <= self.soft_limits[0] + POS_EPS:
                    f |= _SF_SOFT_LIMIT_MINUS
                if x >= self.soft_limits[1] - POS_EPS:
                    f |= _SF_SOFT_LIMIT_PLUS
        if self._traj.is_moving(now):
            f |= _SF_MOVING
        if self.overdrive:
            f |= _SF_OVERDRIVE_MODE
        if self.gstate in (GS.GRIPPING, GS.HOLDING) and any(
                fg.type == FingerType.WSG_FMF and fg.powered and not fg.fault for fg in self.fingers):
            f |= _SF_FORCECNTL_MODE
        if self._temp_state >= 1:
            f |= _SF_TEMP_WARNING
        if self._temp_state >= 2:
            f |= _SF_TEMP_FAULT
        if self.power_fault:
            f |= _SF_POWER_FAULT
        if self.current_fault:
            f |= _SF_CURR_FAULT
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
        self._advance(now)
        m = self._motion
        part = self.obstacles.get("part")
        block = self.obstacles.get("block")
        return Snapshot(
            time=now, width=self.width(now), speed=self.speed(now), force=self.force(now),
            gripper_state=self.gstate, flags=self.system_flags(now), temperature=self.temperature(now),
            force_limit=self.force_limit, acceleration=self.acceleration, soft_limits=self.soft_limits,
            referenced=self.referenced, moving=self.moving(now), target=m.target if m is not None else None,
            overdrive=self.overdrive, fast_stop=self.fast_stopped, model=self.profile.key,
            stroke=self.profile.stroke, statistics=(self.stats[0], self.stats[1], self.stats[2]), tag=self.tag,
            part=part.width if part is not None else None, blocked_at=block.width if block is not None else None,
            script_if=self.script_if, script_of=self.script_of, plugins=tuple(self.plugins),
        )

    # ------------------------------------------------------------------ motion model

    def _motion_event(self, now: float) -> tuple[float, int, str, object] | None:
        """Earliest of: target reached, contact with an obstacle, end stop, soft-limit entry."""
        tr = self._traj
        m = self._motion
        if m is None:
            return None
        if not tr.moving:
            return (max(now, tr.start_time), 1, "end", None)
        best: tuple[float, int, str, object] | None = None
        if math.isfinite(tr.end_time):
            best = (tr.end_time, 1, "end", None)
        for ob in self.obstacles.values():
            t = tr.first_crossing(ob.width, ob.blocks, after=now)
            if t is not None and (best is None or (t, 0) < best[:2]):
                best = (t, 0, "contact", ob)
        if not math.isfinite(tr.end_time):  # moves stay inside the stroke; jogs run to an end stop
            stroke = self.profile.stroke
            for p, d in ((0.0, -1), (stroke, 1)):
                t = tr.first_crossing(p, d, after=now)
                if t is not None and (best is None or (t, 2) < best[:2]):
                    best = (t, 2, "hard", p)
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

    def _start(self, now: float, motion: Motion, traj: Trajectory) -> None:
        self._bits &= ~(_SF_AXIS_STOPPED | _SF_TARGET_POS_REACHED | _SF_BLOCKED_MINUS | _SF_BLOCKED_PLUS)
        self._contact = None
        self._motion = motion
        self._traj = traj
        self._update_load(now)
        self._reschedule(now)
        self._changed()

    def _halt(self, now: float, x: float | None = None) -> None:
        """Fingers stop at once (at ``x`` if given)."""
        pos = self._traj.position(now) if x is None else x
        self._traj = Trajectory.rest(now, pos)

    def _finish(self, status: Status) -> None:
        """Send the running motion's final reply (if it has one) and forget the motion."""
        m = self._motion
        self._motion = None
        if m is not None and m.command_id is not None:
            self._emit(m.session, Frame.reply(m.command_id, status))
            if status != S.E_SUCCESS:
                self._bits |= _SF_CMD_FAILURE

    def _abort_motion(self, status: Status, now: float) -> bool:
        """Stop a running motion (or clamping); returns True if one was running."""
        was = self._motion is not None
        self._halt(now)
        if was:
            self._finish(status)
        if self._contact is not None and self._contact.kind != "hold":
            self._contact = None
        self._update_load(now)
        self._reschedule(now)
        self._changed()
        return was

    def _on_motion_event(self, t: float, kind: str, data: object) -> None:
        m = self._motion
        if m is None:
            return
        if kind == "end":
            self._on_end(t, m)
        elif kind == "contact":
            assert isinstance(data, Obstacle)
            self._on_contact(t, m, data)
        elif kind == "hard":
            assert isinstance(data, float)
            self._halt(t, data)
            d = 1 if data > 0 else -1
            self._bits |= _SF_BLOCKED_PLUS if d > 0 else _SF_BLOCKED_MINUS
            if m.kind == "homing":  # cannot happen: homing targets the end stop
                self._on_end(t, m)
                return
            self._motion = None
            if m.kind in ("prepos", "release", "grip"):
                self._finish_with(m, S.E_RANGE_ERROR if m.kind == "prepos" else S.E_AXIS_BLOCKED)
                self.gstate = GS.IDLE if m.kind != "grip" else GS.NO_PART
            elif m.kind == "jog" or m.kind == "script":
                self.gstate = GS.IDLE
        elif kind == "soft":
            assert isinstance(data, float)
            self._halt(t, data)
            self._fast_stop(t, f"soft limit violated at {data:.2f} mm", interrupted=True)
        self._update_load(t)
        self._changed()

    def _finish_with(self, m: Motion, status: Status) -> None:
        self._motion = m
        self._finish(status)

    def _on_end(self, t: float, m: Motion) -> None:
        x = self._traj.final_x if self._traj.moving else self._traj.position(t)
        self._halt(t, x)
        self._motion = None
        if m.kind == "homing":
            self.referenced = True
            self.gstate = GS.IDLE
            self._bits |= _SF_TARGET_POS_REACHED
            self.log.add(t, LogLevel.INFO, f"homing done at {x:.2f} mm")
            self._finish_with(m, S.E_SUCCESS)
        elif m.kind in ("prepos", "release", "snap", "script"):
            self.gstate = GS.IDLE
            self._bits |= _SF_TARGET_POS_REACHED
            self._finish_with(m, S.E_SUCCESS)
        elif m.kind == "grip":
            # fell through the clamping travel without establishing the force
            self.gstate = GS.NO_PART
            self.stats[1] += 1
            self._finish_with(m, S.E_CMD_FAILED)
        elif m.kind == "lost":
            self.gstate = GS.PART_LOST
        else:  # jog: cannot end by itself
            self.gstate = GS.IDLE

    def _on_contact(self, t: float, m: Motion, ob: Obstacle) -> None:
        x = ob.width
        d = m.direction
        blocked_bit = _SF_BLOCKED_PLUS if d > 0 else _SF_BLOCKED_MINUS
        if m.kind == "grip":
            lo, hi = m.nominal - self.settings.clamping_travel, m.nominal + self.settings.clamping_travel
            if ob.kind == "part" and lo - POS_EPS <= x <= hi + POS_EPS:
                force = self.force_limit
                squeeze = 0.0 if math.isinf(ob.stiffness) else force / ob.stiffness
                self._halt(t, x + d * squeeze)
                self._contact = Contact(ob, d, force, "hold", nominal=m.nominal)
                self.gstate = GS.HOLDING
                self._finish_with(m, S.E_SUCCESS)
            else:
                self._halt(t, x)
                self.gstate = GS.NO_PART
                self.stats[1] += 1
                self._bits |= blocked_bit
                self._finish_with(m, S.E_CMD_FAILED)
            return
        self._halt(t, x)
        self._bits |= blocked_bit
        if m.kind == "prepos":
            if m.stop_on_block:
                self.gstate = GS.IDLE
            else:  # clamp on block: keep pushing with half the nominal force, snap when freed
                self._contact = Contact(ob, d, 0.5 * self.profile.nom_force, "clamp", m.target, m.speed)
            self._finish_with(m, S.E_AXIS_BLOCKED)
        elif m.kind == "homing":
            self.gstate = GS.IDLE
            self.log.add(t, LogLevel.ERROR, f"homing blocked at {x:.2f} mm")
            self._finish_with(m, S.E_AXIS_BLOCKED)
        elif m.kind == "release":
            self.gstate = GS.IDLE
            self._finish_with(m, S.E_AXIS_BLOCKED)
        elif m.kind in ("jog", "script"):
            self._contact = Contact(ob, d, m.force, "press", m.target, m.speed)
            self._motion = None
            if m.kind == "jog":
                self.gstate = GS.IDLE
            else:
                self._finish_with(m, S.E_AXIS_BLOCKED)
        elif m.kind in ("lost", "snap"):
            self._motion = None

    def obstacles_changed(self) -> None:
        """Faults moved an obstacle: re-plan events, release or lose what was held."""
        now = self.clock()
        self._advance(now)
        c = self._contact
        if c is not None and self.obstacles.get(c.obstacle.kind) is not c.obstacle:
            self._contact = None
            x = self._traj.position(now)
            self._bits &= ~(_SF_BLOCKED_MINUS | _SF_BLOCKED_PLUS)
            if c.kind == "hold":
                self.gstate = GS.PART_LOST
                self.stats[2] += 1
                self.log.add(now, LogLevel.WARNING, f"part lost at {x:.2f} mm")
                # the fingers run on to the end of the grip's clamping travel (or one travel further)
                travel = self.settings.clamping_travel
                end = c.nominal + c.direction * travel
                if (end - x) * c.direction <= 0:
                    end = x + c.direction * travel
                end = min(max(end, 0.0), self.profile.stroke)
                self._motion = Motion("lost", None, None, end, self.profile.max_speed / 4, c.direction)
                self._traj = plan_move(now, x, end, self._motion.speed, self.acceleration)
            elif c.kind == "clamp":
                self._motion = Motion("snap", None, None, c.target, c.speed, c.direction)
                self._traj = plan_move(now, x, c.target, max(c.speed, self.profile.min_speed), self.acceleration)
        elif self._motion is None and self._bits & (_SF_BLOCKED_MINUS | _SF_BLOCKED_PLUS):
            self._bits &= ~(_SF_BLOCKED_MINUS | _SF_BLOCKED_PLUS)
        self._update_load(now)
        self._reschedule(now)
        self._changed()
        self._notify()

    # ------------------------------------------------------------------ FAST STOP, faults, temperature

    def _fast_stop(self, now: float, reason: str, interrupted: bool | None = None) -> None:
        was = self._motion is not None
        self._halt(now)
        if was:
            self._finish(S.E_CMD_ABORTED)
        if interrupted or was:
            self.gstate = GS.ERROR
        if self._contact is not None and self._contact.kind != "hold":
            self._contact = None
        self._bits |= _SF_FAST_STOP
        self.log.add(now, LogLevel.ERROR, f"FAST STOP: {reason}")
        self._update_load(now)
        self._reschedule(now)
        self._changed()
        self._notify()

    def reset_gripper_state(self) -> None:
        """Fieldbus STOP/ACK (fieldbus manual §5.5): the gripper state goes back to IDLE.

        Unlike 22h Stop, this also leaves HOLDING, NO_PART, PART_LOST and ERROR; a held part's
        gripping force is released (the fingers stay where they are).
        """
        now = self.clock()
        self._advance(now)
        if self._motion is None:
            self._contact = None
        self.gstate = GS.IDLE
        self._update_load(now)
        self._reschedule(now)
        self._changed()
        self._notify()

    def raise_fast_stop(self, reason: str) -> None:
        """FAST STOP from outside the binary protocol (fieldbus FASTSTOP, parameter change while moving)."""
        now = self.clock()
        self._advance(now)
        self._fast_stop(now, reason)

    def acknowledge_fast_stop(self) -> Status:
        """Acknowledge (24h / fieldbus ACK). E_ACCESS_DENIED while a power or current fault persists."""
        now = self.clock()
        self._advance(now)
        if self.power_fault or self.current_fault:
            return S.E_ACCESS_DENIED
        if self._bits & _SF_FAST_STOP:
            self._bits &= ~_SF_FAST_STOP
            self.log.add(now, LogLevel.INFO, "FAST STOP acknowledged")
            self._changed()
        return S.E_SUCCESS

    def _update_load(self, now: float) -> None:
        c = self._contact
        ratio = c.force / self.profile.nom_force if c is not None else 0.0
        self.thermal.set_load(now, ThermalModel.rise_for(ratio, self._traj.is_moving(now)))

    def _update_temp_flags(self, now: float) -> None:
        temp = self.thermal.temperature(now)
        state = 2 if temp >= FAULT_C else 1 if temp >= WARNING_C else 0
        if state != self._temp_state:
            self._set_temp_state(now, state)

    def _set_temp_state(self, now: float, state: int) -> None:
        old = self._temp_state
        self._temp_state = state
        if state == 2 and old < 2:
            self.log.add(now, LogLevel.ERROR, "temperature fault: motion disabled")
            if self._motion is not None or (self._contact is not None and self._contact.kind != "hold"):
                self._abort_motion(S.E_CMD_ABORTED, now)
                self.gstate = GS.ERROR
        elif state == 1 and old == 0:
            self.log.add(now, LogLevel.WARNING, "temperature warning")
        elif state < old:
            self.log.add(now, LogLevel.INFO, "temperature back below threshold")
        self._changed()

    def _on_temperature(self, t: float) -> None:
        # evaluate just past the crossing so the new state is seen
        self._update_temp_flags(t + 1e-9)

    def heat(self, delta_c: float) -> None:
        now = self.clock()
        self._advance(now)
        self.thermal.heat(now, delta_c)
        self._update_temp_flags(now)
        self._reschedule(now)
        self._changed()
        self._notify()

    def set_power_fault(self, on: bool) -> None:
        """SF_POWER_FAULT: raising it raises FAST STOP; 24h is refused while it persists."""
        self._set_fault("power_fault", on, "power supply out of range", "power supply back in range")

    def set_current_fault(self, on: bool) -> None:
        """SF_CURR_FAULT: raising it raises FAST STOP; 24h is refused while it persists."""
        self._set_fault("current_fault", on, "motor current fault", "motor recovered")

    def _set_fault(self, attr: str, on: bool, raised: str, cleared: str) -> None:
        now = self.clock()
        self._advance(now)
        if on == getattr(self, attr):
            return
        setattr(self, attr, on)
        if on:
            self._fast_stop(now, raised)
        else:
            self.log.add(now, LogLevel.INFO, cleared)
        self._changed()
        self._notify()

    def set_finger_fault(self, n: int, on: bool) -> None:
        now = self.clock()
        self._advance(now)
        f = self.fingers[n]
        f.fault = on
        if on:
            f.powered = False
            f.powering_until = None
            self.log.add(now, LogLevel.ERROR, f"finger {n + 1}: over-current")
        self._changed()
        self._notify()

    # ------------------------------------------------------------------ timers

    def _on_timer(self, t: float, kind: str, args: tuple[object, ...]) -> None:
        if kind == "finger_power":
            n, s, cid = args
            assert isinstance(n, int) and isinstance(cid, int)
            f = self.fingers[n]
            if f.powering_until is not None and f.powering_until <= t:
                f.powering_until = None
                f.powered = True
                self._emit(s if isinstance(s, Session) else None, Frame.reply(cid, S.E_SUCCESS))
                self._changed()

    # ------------------------------------------------------------------ motion API (jog, scripts)

    def _motion_denied(self, now: float, need_reference: bool = True,
                       replaces: tuple[str, ...] = ()) -> Status | None:
        """Why a motion may not start now, or None. ``replaces``: motion kinds it may supersede."""
        if self._bits & _SF_FAST_STOP or self._temp_state >= 2 or self.power_fault or self.current_fault:
            return S.E_ACCESS_DENIED
        m = self._motion
        if (m is not None or self._traj.is_moving(now)) and (m is None or m.kind not in replaces):
            return S.E_ALREADY_RUNNING
        if need_reference and not self.referenced:
            return S.E_NOT_INITIALIZED
        return None

    def _soft_range_error(self, target: float, now: float) -> bool:
        """True if ``target`` lies inside a restricted area (soft limits)."""
        if self.soft_limits is None:
            return False
        lo, hi = self.soft_limits
        return target < lo - SOFT_EPS or target > hi + SOFT_EPS

    def jog(self, direction: int, speed: float, force: float) -> Status:
        """Fieldbus JOG: move at ``speed`` mm/s (0: minimum speed) in ``direction`` (+1 open, -1 close)
        until an end stop, an obstacle (pressing with ``force`` N) or a soft limit; 0 stops."""
        now = self.clock()
        self._advance(now)
        m = self._motion
        if direction == 0:
            if m is not None and m.kind == "jog":
                self._halt(now)
                self._motion = None
                self.gstate = GS.IDLE
                self._update_load(now)
                self._reschedule(now)
                self._changed()
                self._notify()
            return S.E_SUCCESS
        denied = self._motion_denied(now, replaces=("jog",))
        if denied is not None:
            return denied
        d = 1 if direction > 0 else -1
        v = self.profile.clamp_speed(speed if speed > 0 else self.profile.min_speed)
        f = min(max(force, self.profile.min_force), self._max_force())
        if m is not None and m.kind == "jog" and m.direction == d and m.speed == v and m.force == f:
            return S.E_SUCCESS  # level still held: nothing changes
        c = self._contact
        if m is None and c is not None and c.kind == "press" and c.direction == d:
            c.force = f  # still pressing against the same obstacle
            self._changed()
            return S.E_SUCCESS
        self.gstate = GS.POSITIONING
        target = self.profile.stroke if d > 0 else 0.0
        self._start(now, Motion("jog", None, None, target, v, d, force=f),
                    plan_velocity(now, self._traj.position(now), self._traj.velocity(now), d * v,
                                  self.acceleration))
        self._notify()
        return S.E_SUCCESS

    def script_move(self, width: float, speed: float) -> Status:
        """Script ``mc.move``: position to ``width`` mm at ``speed`` mm/s (a running motion is replaced)."""
        now = self.clock()
        self._advance(now)
        denied = self._motion_denied(now, replaces=("script",))
        if denied is not None:
            return denied
        x = self._traj.position(now)
        target = min(max(width, 0.0), self.profile.stroke)
        v = self.profile.clamp_speed(abs(speed))
        d = 1 if target >= x else -1
        self._start(now, Motion("script", None, None, target, v, d, force=self.force_limit),
                    plan_move(now, x, target, v, self.acceleration, v0=self._traj.velocity(now)))
        self._notify()
        return S.E_SUCCESS

    def script_speed(self, velocity: float, force: float | None = None) -> Status:
        """Script ``mc.speed``: run at ``velocity`` mm/s (signed; 0 stops) until blocked."""
        now = self.clock()
        self._advance(now)
        if abs(velocity) < SPEED_EPS:
            if self._motion is not None and self._motion.kind == "script":
                self._halt(now)
                self._motion = None
                self._reschedule(now)
                self._changed()
            return S.E_SUCCESS
        denied = self._motion_denied(now, replaces=("script",))
        if denied is not None:
            return denied
        d = 1 if velocity > 0 else -1
        c = self._contact
        if c is not None and c.kind == "press" and c.direction == d:
            if force is not None:
                c.force = force
            return S.E_SUCCESS  # still pressing against the same obstacle
        v = min(abs(velocity), self.profile.max_speed)
        target = self.profile.stroke if d > 0 else 0.0
        f = self.force_limit if force is None else force
        self._start(now, Motion("script", None, None, target, v, d, force=f),
                    plan_velocity(now, self._traj.position(now), self._traj.velocity(now), d * v,
                                  self.acceleration))
        self._notify()
        return S.E_SUCCESS

    def script_stop(self) -> None:
        now = self.clock()
        self._advance(now)
        if self._motion is not None and self._motion.kind == "script":
            self._halt(now)
            self._motion = None
        if self._contact is not None and self._contact.kind == "press":
            self._contact = None
        self._bits &= ~(_SF_BLOCKED_MINUS | _SF_BLOCKED_PLUS)
        self._update_load(now)
        self._reschedule(now)
        self._changed()

    def set_script_if(self, value: int) -> None:
        """The fieldbus IF user flags (16 bits) changed; running plugins are told."""
        value &= 0xFFFF
        if value == self.script_if:
            return
        self.script_if = value
        for plugin in list(self.plugins.values()):
            plugin.on_if_changed(self, value)
        self._changed()

    def set_script_of(self, value: int) -> None:
        """Set the OF user flags (16 bits), as a script would."""
        self.script_of = value & 0xFFFF
        self._changed()

    def blocked(self) -> bool:
        return bool(self._bits & (_SF_BLOCKED_MINUS | _SF_BLOCKED_PLUS))

    def _max_force(self) -> float:
        return self.profile.ovr_force if self.overdrive else self.profile.nom_force

    # ------------------------------------------------------------------ plugins

    def load_plugin(self, plugin: str | FirmwarePlugin) -> FirmwarePlugin:
        """Start a firmware plugin (by name or instance); its command IDs become known."""
        from .plugins import PLUGINS

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
        self.script_failure = False
        inst.start(self)
        self.log.add(self.clock(), LogLevel.INFO, f"script {inst.name} started")
        self._changed()
        return inst

    def unload_plugin(self, name: str) -> None:
        inst = self.plugins.pop(name, None)
        if inst is None:
            return
        for cid in inst.commands:
            if self._plugin_cmds.get(cid) is inst:
                del self._plugin_cmds[cid]
        inst.stop(self)
        self.log.add(self.clock(), LogLevel.INFO, f"script {name} stopped")
        self._changed()

    # ------------------------------------------------------------------ command handlers

    def _build_dispatch(self) -> dict[int, tuple[Callable[[Session, bytes, float], Frame], int | None]]:
        def fixed(cid: int) -> int | None:
            layout = CATALOG[cid].request_layout
            return None if layout.variable is not None else layout.fixed_size

        h: dict[int, Callable[[Session, bytes, float], Frame]] = {
            0x06: self._cmd_loop, 0x07: self._cmd_disconnect, 0x20: self._cmd_homing,
            0x21: self._cmd_preposition, 0x22: self._cmd_stop, 0x23: self._cmd_fast_stop,
            0x24: self._cmd_ack, 0x25: self._cmd_grip, 0x26: self._cmd_release,
            0x30: self._cmd_set_acc, 0x31: self._cmd_get_acc, 0x32: self._cmd_set_force,
            0x33: self._cmd_get_force_limit, 0x34: self._cmd_set_soft, 0x35: self._cmd_get_soft,
            0x36: self._cmd_clear_soft, 0x37: self._cmd_overdrive, 0x38: self._cmd_tare,
            0x42: self._cmd_stats, 0x46: self._cmd_temperature,
            0x50: self._cmd_info, 0x51: self._cmd_set_tag, 0x52: self._cmd_get_tag, 0x53: self._cmd_limits,
        }
        for cid in AUTO_UPDATE_IDS:
            h[cid] = partial(self._auto_update, cid=int(cid))
        for n, base in ((0, 0x60), (1, 0x70)):
            h[base] = partial(self._cmd_finger_info, n=n, cid=base)
            h[base + 1] = partial(self._cmd_finger_flags, n=n, cid=base + 1)
            h[base + 2] = partial(self._cmd_finger_power, n=n, cid=base + 2)
            h[base + 3] = partial(self._cmd_finger_data, n=n, cid=base + 3)
        return {cid: (fn, fixed(cid)) for cid, fn in h.items()}

    # 3.1 connection management

    def _cmd_loop(self, s: Session, payload: bytes, now: float) -> Frame:
        if len(payload) > 256:
            return Frame.reply(0x06, S.E_CMD_FORMAT_ERROR)
        if not payload:
            return Frame.reply(0x06, S.E_INVALID_PARAMETER)  # nothing to loop: "parameter value undefined"
        return Frame.reply(0x06, S.E_SUCCESS, payload)

    def _cmd_disconnect(self, s: Session, payload: bytes, now: float) -> Frame:
        if not s.connection_oriented:
            return Frame.reply(0x07, S.E_NOT_AVAILABLE)
        s.announced = True
        s.subscriptions.clear()
        if self._motion is not None or self._traj.is_moving(now):
            self._abort_motion(S.E_CMD_ABORTED, now)
            if self.gstate in (GS.GRIPPING, GS.RELEASING, GS.POSITIONING):
                self.gstate = GS.IDLE
        self.log.add(now, LogLevel.INFO, f"disconnect announced by {s.peer or s.kind}")
        self._changed()
        return Frame.reply(0x07, S.E_SUCCESS)

    # 3.2 motion control

    def _cmd_homing(self, s: Session, payload: bytes, now: float) -> Frame:
        denied = self._motion_denied(now, need_reference=False)
        if denied is not None:
            return Frame.reply(0x20, denied)
        direction = payload[0]
        if direction not in (0, 1, 2):
            return Frame.reply(0x20, S.E_INVALID_PARAMETER)
        if direction == HomingDirection.DEFAULT:
            direction = self.settings.homing_direction
        d = 1 if direction == HomingDirection.POSITIVE else -1
        self.script_stop_if_running(now)
        target = self.profile.stroke if d > 0 else 0.0
        x = self._traj.position(now)
        self.referenced = False
        self.gstate = GS.POSITIONING
        self._start(now, Motion("homing", s, 0x20, target, self.profile.homing_speed, d),
                    plan_move(now, x, target, self.profile.homing_speed, self.acceleration))
        self.log.add(now, LogLevel.INFO, f"homing in {'positive' if d > 0 else 'negative'} direction")
        return Frame.reply(0x20, S.E_CMD_PENDING)

    def script_stop_if_running(self, now: float) -> None:
        m = self._motion
        if m is not None and m.kind in ("jog", "script"):
            self._halt(now)
            self._motion = None

    def _check_width(self, cid: int, width: float, speed: float) -> Frame | None:
        if not (math.isfinite(width) and math.isfinite(speed)):
            return Frame.reply(cid, S.E_INVALID_PARAMETER)
        return None

    def _cmd_preposition(self, s: Session, payload: bytes, now: float) -> Frame:
        flags, width, speed = _PREPOS.unpack(payload)
        bad = self._check_width(0x21, width, speed)
        if bad is not None:
            return bad
        denied = self._motion_denied(now)
        if denied is not None:
            return Frame.reply(0x21, denied)
        x = self._traj.position(now)
        target = x + width if flags & PrepositionFlag.RELATIVE else width
        target = min(max(target, 0.0), self.profile.stroke)  # outside the stroke: clamped
        if self._soft_range_error(target, now):
            return Frame.reply(0x21, S.E_RANGE_ERROR)
        self.script_stop_if_running(now)
        v = self.profile.clamp_speed(speed)
        d = 1 if target >= x else -1
        if self._contact is not None and self._contact.kind == "hold":
            self._contact = None  # leaving the part
        self.gstate = GS.POSITIONING
        self._start(now, Motion("prepos", s, 0x21, target, v, d,
                                stop_on_block=bool(flags & PrepositionFlag.STOP_ON_BLOCK)),
                    plan_move(now, x, target, v, self.acceleration))
        return Frame.reply(0x21, S.E_CMD_PENDING)

    def _cmd_stop(self, s: Session, payload: bytes, now: float) -> Frame:
        was = self._abort_motion(S.E_CMD_ABORTED, now)
        self._bits |= _SF_AXIS_STOPPED
        self._bits &= ~(_SF_BLOCKED_MINUS | _SF_BLOCKED_PLUS)
        if was and self.gstate in (GS.GRIPPING, GS.RELEASING, GS.POSITIONING):
            self.gstate = GS.IDLE
        self._changed()
        return Frame.reply(0x22, S.E_SUCCESS)

    def _cmd_fast_stop(self, s: Session, payload: bytes, now: float) -> Frame:
        # executed whatever the payload: an emergency stop must never be refused
        self._fast_stop(now, f"command 23h from {s.peer or s.kind}")
        return Frame.reply(0x23, S.E_SUCCESS)

    def _cmd_ack(self, s: Session, payload: bytes, now: float) -> Frame:
        if payload != b"ack":
            return Frame.reply(0x24, S.E_CMD_FORMAT_ERROR)
        return Frame.reply(0x24, self.acknowledge_fast_stop())

    def _cmd_grip(self, s: Session, payload: bytes, now: float) -> Frame:
        width, speed = _GRIP.unpack(payload)
        bad = self._check_width(0x25, width, speed)
        if bad is not None:
            return bad
        denied = self._motion_denied(now)
        if denied is not None:
            return Frame.reply(0x25, denied)
        if self._soft_range_error(width, now):
            return Frame.reply(0x25, S.E_RANGE_ERROR)
        x = self._traj.position(now)
        nominal = min(max(width, 0.0), self.profile.stroke)
        d = -1 if nominal < x else 1
        c = self._contact
        if c is not None and c.kind == "hold":
            if c.direction != d:
                return Frame.reply(0x25, S.E_ACCESS_DENIED)  # against the held part
            d = c.direction
        self.script_stop_if_running(now)
        target = min(max(nominal + d * self.settings.clamping_travel, 0.0), self.profile.stroke)
        v = self.profile.clamp_speed(speed)
        self.gstate = GS.GRIPPING
        self.stats[0] += 1
        if c is not None and c.kind == "hold":
            # re-grip in the same direction: lift off the part first (the part stays where it is)
            x = c.obstacle.width - d * 1e-6
        self._start(now, Motion("grip", s, 0x25, target, v, d, nominal=nominal),
                    plan_move(now, x, target, v, self.acceleration))
        return Frame.reply(0x25, S.E_CMD_PENDING)

    def _cmd_release(self, s: Session, payload: bytes, now: float) -> Frame:
        width, speed = _RELEASE.unpack(payload)
        bad = self._check_width(0x26, width, speed)
        if bad is not None:
            return bad
        denied = self._motion_denied(now)
        if denied is not None:
            return Frame.reply(0x26, denied)
        target = min(max(width, 0.0), self.profile.stroke)
        if self._soft_range_error(target, now):
            return Frame.reply(0x26, S.E_RANGE_ERROR)
        self.script_stop_if_running(now)
        x = self._traj.position(now)
        v = self.profile.clamp_speed(speed)
        d = 1 if target >= x else -1
        self.gstate = GS.RELEASING
        self._start(now, Motion("release", s, 0x26, target, v, d), plan_move(now, x, target, v, self.acceleration))
        return Frame.reply(0x26, S.E_CMD_PENDING)

    # 3.3 motion configuration

    def _cmd_set_acc(self, s: Session, payload: bytes, now: float) -> Frame:
        (acc,) = _F32.unpack(payload)
        if math.isnan(acc):
            return Frame.reply(0x30, S.E_INVALID_PARAMETER)
        self.acceleration = self.profile.clamp_acc(acc)
        return Frame.reply(0x30, S.E_SUCCESS)

    def _cmd_get_acc(self, s: Session, payload: bytes, now: float) -> Frame:
        return Frame.reply(0x31, S.E_SUCCESS, _F32.pack(self.acceleration))

    def _cmd_set_force(self, s: Session, payload: bytes, now: float) -> Frame:
        (force,) = _F32.unpack(payload)
        if math.isnan(force):
            return Frame.reply(0x32, S.E_INVALID_PARAMETER)
        self.force_limit = min(max(force, self.profile.min_force), self._max_force())
        return Frame.reply(0x32, S.E_SUCCESS)

    def _cmd_get_force_limit(self, s: Session, payload: bytes, now: float) -> Frame:
        return Frame.reply(0x33, S.E_SUCCESS, _F32.pack(self.force_limit))

    def _cmd_set_soft(self, s: Session, payload: bytes, now: float) -> Frame:
        minus, plus = _SOFT.unpack(payload)
        if not (math.isfinite(minus) and math.isfinite(plus)) or minus > plus:
            return Frame.reply(0x34, S.E_INVALID_PARAMETER)
        stroke = self.profile.stroke
        self.soft_limits = (min(max(minus, 0.0), stroke), min(max(plus, 0.0), stroke))
        self.log.add(now, LogLevel.INFO, f"soft limits set: {minus:.2f} .. {plus:.2f} mm")
        self._reschedule(now)
        self._changed()
        return Frame.reply(0x34, S.E_SUCCESS)

    def _cmd_get_soft(self, s: Session, payload: bytes, now: float) -> Frame:
        if self.soft_limits is None:
            return Frame.reply(0x35, S.E_NOT_AVAILABLE)
        return Frame.reply(0x35, S.E_SUCCESS, _SOFT.pack(*self.soft_limits))

    def _cmd_clear_soft(self, s: Session, payload: bytes, now: float) -> Frame:
        if self.soft_limits is not None:
            self.soft_limits = None
            self.log.add(now, LogLevel.INFO, "soft limits cleared")
            self._reschedule(now)
            self._changed()
        return Frame.reply(0x36, S.E_SUCCESS)

    def _cmd_overdrive(self, s: Session, payload: bytes, now: float) -> Frame:
        on = bool(payload[0] & 1)
        if payload[0] & 0xFE:
            return Frame.reply(0x37, S.E_INVALID_PARAMETER)
        if on != self.overdrive:
            self.overdrive = on
            self.log.add(now, LogLevel.WARNING if on else LogLevel.INFO,
                         "overdrive mode entered" if on else "overdrive mode left")
            if not on and self.force_limit > self.profile.nom_force:
                self.force_limit = self.profile.nom_force
                if self._contact is not None and self._contact.kind == "hold":
                    self._contact.force = self.force_limit
                    self._update_load(now)
                    self._reschedule(now)
            self._changed()
        return Frame.reply(0x37, S.E_SUCCESS)

    def _cmd_tare(self, s: Session, payload: bytes, now: float) -> Frame:
        fmf = [f for f in self.fingers if f.type == FingerType.WSG_FMF]
        if not fmf:
            return Frame.reply(0x38, S.E_NOT_AVAILABLE)
        if self.gstate == GS.HOLDING:
            return Frame.reply(0x38, S.E_ACCESS_DENIED)
        force = self.force(now)
        for f in fmf:
            f.tare_offset = f.fmf_force(force) + f.tare_offset - force
        self.log.add(now, LogLevel.INFO, "force sensor tared")
        return Frame.reply(0x38, S.E_SUCCESS)

    # 3.4 system state

    def _cmd_stats(self, s: Session, payload: bytes, now: float) -> Frame:
        flags = payload[0]
        t, n, lost = self.stats
        reply = Frame.reply(0x42, S.E_SUCCESS, _STATS.pack(t & 0xFFFFFFFF, min(n, 0xFFFF), min(lost, 0xFFFF)))
        if flags & 1:
            self.stats = [0, 0, 0]
            self.log.add(now, LogLevel.INFO, "gripping statistics reset")
        return reply

    def _cmd_temperature(self, s: Session, payload: bytes, now: float) -> Frame:
        return Frame.reply(0x46, S.E_SUCCESS, _TEMP.pack(round(self.thermal.temperature(now) * 10)))

    # 3.5 system configuration

    def _cmd_info(self, s: Session, payload: bytes, now: float) -> Frame:
        p = self.profile
        return Frame.reply(0x50, S.E_SUCCESS, _INFO.pack(int(p.device_type), p.hwrev, p.fw_version,
                                                         self.serial_number))

    def _cmd_set_tag(self, s: Session, payload: bytes, now: float) -> Frame:
        if len(payload) > 64:
            return Frame.reply(0x51, S.E_OVERRUN)
        if not payload or any(b < 0x20 or b > 0x7E for b in payload):
            return Frame.reply(0x51, S.E_INVALID_PARAMETER)
        self.tag = payload.decode("ascii")
        return Frame.reply(0x51, S.E_SUCCESS)

    def _cmd_get_tag(self, s: Session, payload: bytes, now: float) -> Frame:
        if self.tag is None:
            return Frame.reply(0x52, S.E_NOT_AVAILABLE)
        return Frame.reply(0x52, S.E_SUCCESS, self.tag.encode("ascii"))

    def _cmd_limits(self, s: Session, payload: bytes, now: float) -> Frame:
        p = self.profile
        return Frame.reply(0x53, S.E_SUCCESS, _LIMITS.pack(p.stroke, p.min_speed, p.max_speed, p.min_acc,
                                                           p.max_acc, p.min_force, p.nom_force, p.ovr_force))

    # 3.6 finger interface

    def _cmd_finger_info(self, s: Session, payload: bytes, now: float, n: int, cid: int) -> Frame:
        f = self.fingers[n]
        return Frame.reply(cid, S.E_SUCCESS, _FINGER_INFO.pack(int(f.type), f.frame_size))

    def _cmd_finger_flags(self, s: Session, payload: bytes, now: float, n: int, cid: int) -> Frame:
        f = self.fingers[n]
        return Frame.reply(cid, S.E_SUCCESS, _U16.pack(int(f.flags())))

    def _cmd_finger_power(self, s: Session, payload: bytes, now: float, n: int, cid: int) -> Frame:
        f = self.fingers[n]
        on = payload[0]
        if on not in (0, 1):
            return Frame.reply(cid, S.E_INVALID_PARAMETER)
        if f.type != FingerType.GENERIC:
            return Frame.reply(cid, S.E_ACCESS_DENIED)  # predefined fingers are not switchable
        if not on:
            f.powered = False
            f.powering_until = None
            self._changed()
            return Frame.reply(cid, S.E_SUCCESS)
        if f.fault:
            return Frame.reply(cid, S.E_CMD_FAILED)  # over-current while enabling
        if f.powering_until is not None:
            return Frame.reply(cid, S.E_ALREADY_RUNNING)
        f.powered = False
        f.powering_until = now + POWER_UP_S
        self._schedule(now + POWER_UP_S, "finger_power", n, s, cid)
        self._changed()
        return Frame.reply(cid, S.E_CMD_PENDING)

    def _cmd_finger_data(self, s: Session, payload: bytes, now: float, n: int, cid: int) -> Frame:
        f = self.fingers[n]
        if f.type == FingerType.GENERIC:
            return Frame.reply(cid, S.E_NOT_AVAILABLE)
        if f.fault or f.comm_fault or not f.powered:
            return Frame.reply(cid, S.E_IO_ERROR)
        c = self._contact
        return Frame.reply(cid, S.E_SUCCESS, f.data(self.force(now), c is not None and c.kind == "hold"))



def _fw(v: int) -> str:
    major, m1, m2, rc = (v >> 12) & 15, (v >> 8) & 15, (v >> 4) & 15, v & 15
    return f"{major}.{m1}.{m2}" + (f"-rc{rc}" if rc else "")


def _changed(cid: int, old: float | int | None, new: float | int) -> bool:
    if old is None:
        return True
    threshold = CHANGE_THRESHOLDS.get(cid)
    if threshold is None:
        return old != new
    return abs(float(new) - float(old)) >= threshold - 1e-9
