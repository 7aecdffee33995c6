"""The virtual gripper's public facade: frames in, frames out, on an injected clock (sans-IO).

Requests come in through :meth:`VirtualGripper.feed` / :meth:`handle_frame` /
:meth:`handle_datagram` and are answered at once; everything that happens later (final replies of
motions, auto-update packets, finger power-up) is collected by :meth:`poll`, and
:meth:`next_due` says when to call it next. Nothing here sleeps or touches a socket.

This module is the firmware's front door only: power-up and settings, sessions, parsing and
dispatch through :data:`~pywsg.device.handlers.HANDLERS`. What the commands do lives in
:mod:`~pywsg.device.handlers`, what the fingers do in :mod:`~pywsg.device.axis`, the device-wide
rules (FAST STOP, faults, readings) in :mod:`~pywsg.device.core`.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from functools import partial

from ..protocol import (
    CATALOG,
    MAX_PAYLOAD,
    ChecksumMismatch,
    Command,
    Frame,
    FrameParser,
    FrameTooLarge,
    GripperState,
    ParseError,
    Status,
    SystemFlag,
    Truncated,
    parse_datagram,
)
from .axis import Axis
from .clock import Clock, monotonic_clock
from .core import DeviceCore, Snapshot
from .fingers import Finger
from .handlers import HANDLERS, length_error, request_size
from .health import Health
from .log import LogLevel
from .plugins import FirmwarePlugin
from .profiles import get_profile
from .session import Deliver, Session
from .settings import Settings
from .thermal import ThermalModel

__all__ = ["QUERY_IDS", "Snapshot", "VirtualGripper"]

S = Status

_SF_CMD_FAILURE = int(SystemFlag.SF_CMD_FAILURE)
# reads: a well-formed one neither sets nor clears SF_CMD_FAILURE ("the last command returned an
# error"). A poll would otherwise clear it before it could be read, and a read that finds nothing
# (52h without a tag, 35h without soft limits, 63h of a generic finger) would raise it: no read may
# change what the gripper reports. A malformed read (wrong length, bad parameter) still raises it.
QUERY_IDS = frozenset((0x06, 0x31, 0x33, 0x35, 0x40, 0x41, 0x42, 0x43, 0x44, 0x45, 0x46, 0x50, 0x52, 0x53,
                       0x60, 0x61, 0x63, 0x70, 0x71, 0x73))
_E_CMD_PENDING = int(Status.E_CMD_PENDING)
_NOTHING_TO_READ = frozenset((int(Status.E_NOT_AVAILABLE), int(Status.E_IO_ERROR)))
_REQUEST_CACHE_SIZE = 256
_REQUEST_CACHE_BYTES = 64

# command ID -> (handler bound to the device, fixed request size or None, status for a wrong length)
Dispatch = dict[int, tuple[Callable[[Session, bytes, float], Frame], int | None, Status]]
#: ``fn(session, command_id)``: a request is about to be executed.
CommandListener = Callable[[Session, int], None]
#: ``fn(old, new)``: the gripper state (41h) changed.
StateListener = Callable[[GripperState, GripperState], None]


def _max_request(command_id: int) -> int:
    spec = CATALOG.get(command_id)
    if spec is None:
        return MAX_PAYLOAD
    size = spec.max_request_size
    # let a stray payload to a no-parameter command through, to answer E_NO_PARAM_EXPECTED
    return size if size else 64


# the parser asks for every frame: one table lookup instead of a catalog walk
_MAX_REQUEST: tuple[int, ...] = tuple(_max_request(i) for i in range(256))



_STATUS_REPLIES: dict[tuple[int, int], Frame] = {}


def _status_reply(command_id: int, status: Status) -> Frame:
    """``Frame.reply(command_id, status)``, made once per pair (frames are immutable): a flood of bad
    frames costs a dictionary lookup per answer."""
    key = (command_id, int(status))
    frame = _STATUS_REPLIES.get(key)
    if frame is None:
        frame = _STATUS_REPLIES[key] = Frame.reply(command_id, status)
    return frame

class VirtualGripper(DeviceCore):
    """A WSG that answers every command of the command manual like the real one.

    ``model``: profile key (None: ``settings.model``); ``clock``: seconds, defaults to
    :func:`time.monotonic` (tests pass a :class:`~pywsg.device.ManualClock`).
    """

    def __init__(self, model: str | None = None, settings: Settings | None = None,
                 clock: Clock | None = None) -> None:
        settings = settings or Settings()
        if model is not None:
            settings = settings.updated(model=get_profile(model).key)
        super().__init__(clock or monotonic_clock)
        # the handler table bound to this device: one call per request, no lookup on the class
        self._dispatch: Dispatch = {cid: (partial(fn, self), request_size(cid), length_error(cid))
                                   for cid, fn in HANDLERS.items()}
        # requests seen before, as their exact bytes (a polling client repeats them): parsed once.
        # Only frames with a valid checksum go in, so a hit is right whatever the CRC setting.
        self._requests: dict[bytes, Frame] = {}
        self._command_listeners: list[CommandListener] = []
        self._state_listeners: list[StateListener] = []
        self._transitions: list[tuple[GripperState, GripperState]] = []  # the axis records, we report
        self.settings = settings
        self._power_up(settings)

    # ------------------------------------------------------------------ power-up / settings

    def _power_up(self, settings: Settings) -> None:
        """(Re)start the device: session values back to their defaults, not referenced."""
        now = self.clock()
        self.profile = p = get_profile(settings.model)
        self.settings = settings
        self.serial_number = settings.serial_number if settings.serial_number is not None else p.serial_number
        self.thermal = ThermalModel(now)
        before = self.axis.gstate if hasattr(self, "axis") else GripperState.IDLE
        self.axis = Axis(self, p, self.log, self.thermal, now, settings.acceleration, settings.force_limit,
                         settings.clamping_travel)
        if self._state_listeners:
            self.axis.transitions = self._transitions
            if before != GripperState.IDLE:  # a restart: the new axis starts IDLE
                self._transitions.append((before, GripperState.IDLE))
        self._event = None
        self._bits = 0
        self.tag = settings.tag  # kept in the settings (file): a restart keeps it
        self.fingers = [Finger.of(settings.finger1), Finger.of(settings.finger2)]
        self.health = Health(self.thermal, self.log)
        self.script_if = 0
        self.script_of = 0
        self.script_failure = False
        self.schedule.next_event = math.inf
        self.schedule.due_valid = False
        for name in list(self.plugins):
            self.unload_plugin(name)
        if settings.script:
            self.load_plugin(settings.script)
        self.log.add(now, LogLevel.INFO, f"{p.name} started (firmware {_fw(p.fw_version)}, SN {self.serial_number})")
        self.changed()
        if settings.auto_homing:
            self._auto_home()

    def _auto_home(self) -> None:
        """Auto-homing at power-up: an ordinary 20h from an internal session, so every rule holds."""
        startup = next((s for s in self.streams.sessions if s.kind == "startup"), None)
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
            self.abort_motion(S.E_CMD_ABORTED, self.clock())
            self._power_up(settings)
        else:
            self.settings = settings
            self.axis.clamping_travel = settings.clamping_travel
            if settings.script != old.script:
                for name in list(self.plugins):
                    self.unload_plugin(name)
                if settings.script:
                    self.load_plugin(settings.script)
        for s in self.streams.sessions:
            s.parser.verify_checksum = settings.crc_check
        self.log.add(self.clock(), LogLevel.INFO, "settings changed")
        self.changed()

    def restart(self) -> None:
        """Power-cycle: session values (acceleration, force limit, soft limits) are lost; the tag is kept."""
        now = self.clock()
        self.abort_motion(S.E_CMD_ABORTED, now)
        self._power_up(self.settings)

    # ------------------------------------------------------------------ sessions

    def open_session(self, kind: str = "tcp", peer: str = "", deliver: Deliver | None = None) -> Session:
        """A new client session. Only one TCP client holds the command interface at a time; a second
        one is served but every command gets E_ACCESS_DENIED."""
        s = self.streams.open(kind, peer, deliver, FrameParser(self.settings.crc_check, self._max_payload))
        if s.denied:
            self.log.add(self.clock(), LogLevel.WARNING, f"second TCP client {peer} refused: command interface in use")
        return s

    def close_session(self, s: Session) -> None:
        """The client went away. An unannounced TCP close raises FAST STOP (setting)."""
        if s.closed:
            return
        now = self.clock()
        self.advance(now)
        if self.streams.close(s) and not s.announced and self.settings.fast_stop_on_disconnect:
            self.fast_stop(now, "unannounced disconnect of TCP client " + (s.peer or "?"))
        self.changed()
        if self._transitions:
            self._report_states()

    @property
    def sessions(self) -> list[Session]:
        return list(self.streams.sessions)

    def add_wakeup_listener(self, fn: Callable[[], None]) -> None:
        """``fn()`` is called whenever :meth:`next_due` may have moved earlier."""
        self.schedule.listeners.append(fn)

    def remove_wakeup_listener(self, fn: Callable[[], None]) -> None:
        if fn in self.schedule.listeners:
            self.schedule.listeners.remove(fn)

    def add_command_listener(self, fn: CommandListener) -> None:
        """``fn(session, command_id)`` is called before each request is executed, from any interface
        (TCP, UDP, serial, CAN, the fieldbus's own session), before the device catches up with the
        clock. Not for refused sessions (a second TCP client, one after 07h): their frames change
        nothing. ``fn`` may act on the device (place a part, raise a fault); the request then meets
        that world. Exceptions from ``fn`` propagate to the caller of :meth:`handle_frame`."""
        self._command_listeners.append(fn)

    def remove_command_listener(self, fn: CommandListener) -> None:
        if fn in self._command_listeners:
            self._command_listeners.remove(fn)

    def add_state_listener(self, fn: StateListener) -> None:
        """``fn(old, new)`` is called for every change of the gripper state (41h), in order, also for
        states that last no time at all (GRIPPING → HOLDING → PART_LOST within one :meth:`poll`).

        Calls come when the :meth:`handle_frame`, :meth:`poll` or :meth:`close_session` that made the
        change is done with the device, never in the middle of an update, so ``fn`` may act on the
        device; ``self.clock()`` is the time. A change made by another call (fault injection,
        :meth:`jog`, :meth:`reset_gripper_state`) is reported by the next of those three."""
        self._state_listeners.append(fn)
        self.axis.transitions = self._transitions

    def remove_state_listener(self, fn: StateListener) -> None:
        if fn in self._state_listeners:
            self._state_listeners.remove(fn)
        if not self._state_listeners:
            self.axis.transitions = None
            self._transitions.clear()

    def _report_states(self) -> None:
        """Hand the recorded state changes to the state listeners (changes they cause are next)."""
        pending = self._transitions
        for _ in range(10_000):  # bounded: listeners that keep changing the state cannot spin forever
            if not pending:
                return
            batch = pending[:]
            pending.clear()
            for old, new in batch:
                for fn in list(self._state_listeners):
                    fn(old, new)

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
        if now >= self.schedule.next_event:  # as handle_frame: nothing is due before next_event
            self.advance(now)
        streams = self.streams
        out = streams.take(s) if streams.outbox else []
        if s.denied or s.announced or s.closed:  # refused: answered, and nothing of the device changes
            out.append(_status_reply(command_id, S.E_ACCESS_DENIED))
            return out
        out.append(_status_reply(command_id, status))
        if not self._bits & _SF_CMD_FAILURE:  # a flood of bad frames changes the state once, not per frame
            self._bits |= _SF_CMD_FAILURE
            self.changed()
        return out

    def handle_frame(self, s: Session, frame: Frame) -> list[Frame]:
        """Execute one request; returns the immediate replies (deferred ones come from :meth:`poll`)."""
        if self._command_listeners and not (s.denied or s.announced or s.closed):
            for fn in list(self._command_listeners):
                fn(s, frame.command_id)
        now = self.clock()
        schedule = self.schedule
        if now >= schedule.next_event:
            self.advance(now)
        streams = self.streams
        out = streams.take(s) if streams.outbox else []
        cid = frame.command_id
        payload = frame.payload
        if s.denied or s.announced or s.closed:
            # a refused client (a second TCP client, or one after 07h) is answered E_ACCESS_DENIED and
            # touches nothing: not SF_CMD_FAILURE, which belongs to the controlling client
            out.append(Frame.reply(cid, S.E_ACCESS_DENIED))
            return out
        entry = self._dispatch.get(cid)
        if entry is None:
            plugin = self._plugin_cmds.get(cid)
            reply = Frame.reply(cid, S.E_CMD_UNKNOWN) if plugin is None else self._script_request(plugin, s, frame, now)
        else:
            handler, size, length_status = entry
            if size is not None and len(payload) != size and cid != Command.FAST_STOP:
                reply = Frame.reply(cid, length_status)
            else:
                reply = handler(s, payload, now)
        if streams.outbox:
            out.extend(streams.take(s))
        out.append(reply)
        p = reply.payload
        code = p[0] | (p[1] << 8)
        if cid in QUERY_IDS and (code == 0 or code in _NOTHING_TO_READ):
            pass  # a read changes nothing the gripper reports (docs/fidelity.md)
        elif code != 0 and code != _E_CMD_PENDING:
            if not self._bits & _SF_CMD_FAILURE:
                self._bits |= _SF_CMD_FAILURE
                schedule.changed()
        elif cid not in QUERY_IDS and self._bits & _SF_CMD_FAILURE:
            self._bits &= ~_SF_CMD_FAILURE
            schedule.changed()
        if not schedule.due_valid:
            schedule.notify()
        if self._transitions:
            self._report_states()
        return out

    # ------------------------------------------------------------------ time: poll / next_due

    def _script_request(self, plugin: FirmwarePlugin, s: Session, frame: Frame, now: float) -> Frame:
        """A request for a script's command ID; a script error aborts the script (000 App. B D20 SF_SCRIPT_FAILURE).

        The failed request is answered E_CMD_FAILED (the manuals do not say; docs/fidelity.md).
        """
        cid = frame.command_id
        try:
            return plugin.handle(self, s, cid, frame.payload, now)
        except Exception as exc:
            self.abort_script(plugin.name, exc)
            return Frame.reply(cid, S.E_CMD_FAILED)

    def poll(self) -> list[tuple[Session, Frame]]:
        """Everything due at ``clock()``: final replies, auto-updates, power-up completions.

        Each frame is also passed to its session's ``deliver`` callback, if set. Cheap when
        nothing is due.
        """
        now = self.clock()
        schedule = self.schedule
        if schedule.due_valid and (schedule.due_cache is None or now < schedule.due_cache):
            if self._transitions:
                self._report_states()
            return []
        self.advance(now)
        streams = self.streams
        streams.run(now)
        due = streams.outbox
        streams.outbox = []
        for s, f in due:
            if s.deliver is not None and not s.closed:
                s.deliver(f)
        schedule.due_valid = False
        if self._transitions:
            self._report_states()
        return due

    def next_due(self) -> float | None:
        """Clock time of the next event (final reply, auto-update, power-up, temperature threshold)."""
        schedule = self.schedule
        if schedule.due_valid:
            return schedule.due_cache
        t = schedule.next_event
        due = self.streams.next_due(self.clock(), t if t != math.inf else None)
        schedule.due_cache = due
        schedule.due_valid = True
        return due


def _fw(v: int) -> str:
    major, m1, m2, rc = (v >> 12) & 15, (v >> 8) & 15, (v >> 4) & 15, v & 15
    return f"{major}.{m1}.{m2}" + (f"-rc{rc}" if rc else "")
