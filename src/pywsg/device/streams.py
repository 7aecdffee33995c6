"""Client sessions, their outboxes and auto-update streams (000 §3.4: 40h, 41h, 43h–45h with FLAGS D0).

:class:`Streams` knows who is connected, which TCP client holds the command interface, which frames
wait for which session, and when each auto-update subscription is due. It reads device values only
through the ``value_for`` / ``moving`` callables it is given, so it knows nothing of the axis.
"""

from __future__ import annotations

import struct
from collections.abc import Callable

from ..protocol import CATALOG, AutoUpdateFlag, Command, Frame, FrameParser, Status
from .schedule import Schedule
from .session import Deliver, Session, Subscription

_U8 = struct.Struct("<B")
_U32 = struct.Struct("<I")
_F32 = struct.Struct("<f")
_AUTO = CATALOG[Command.GET_SYSTEM_STATE].request_layout.struct  # FLAGS u8, PERIOD_MS u16
_AUTO_UPDATE = int(AutoUpdateFlag.AUTO_UPDATE)
_CHANGE_ONLY = int(AutoUpdateFlag.CHANGE_ONLY)
_OK = b"\x00\x00"  # E_SUCCESS status bytes
# plain ints for the hot paths (comparing with an IntEnum member looks it up on the class each time)
_ID_SYSTEM_STATE = int(Command.GET_SYSTEM_STATE)
_ID_GRIPPER_STATE = int(Command.GET_GRIPPER_STATE)

MIN_PERIOD_MS = 10
CHANGE_THRESHOLDS: dict[int, float] = {  # the manual's change thresholds for change-only updates
    Command.GET_OPENING_WIDTH: 0.01,  # mm
    Command.GET_SPEED: 0.05,  # mm/s
    Command.GET_FORCE: 0.05,  # N
}
AUTO_UPDATE_IDS = frozenset((Command.GET_SYSTEM_STATE, Command.GET_GRIPPER_STATE, Command.GET_OPENING_WIDTH,
                             Command.GET_SPEED, Command.GET_FORCE))

ValueFor = Callable[[int, float], "float | int"]


class Streams:
    """Sessions, the frames due to them, and their auto-update subscriptions."""

    def __init__(self, schedule: Schedule, value_for: ValueFor, moving: Callable[[float], bool]) -> None:
        self.schedule = schedule
        self.value_for = value_for
        self.moving = moving
        self.sessions: list[Session] = []
        self.tcp_holder: Session | None = None
        self.outbox: list[tuple[Session, Frame]] = []
        self._value_frames: dict[int, Frame] = {}  # last value frame per ID (values repeat at rest)

    # ------------------------------------------------------------------ sessions

    def open(self, kind: str, peer: str, deliver: Deliver | None, parser: FrameParser) -> Session:
        """Register a session; a second TCP client while one holds the interface is ``denied``."""
        s = Session(kind, peer, deliver)
        s.parser = parser
        if kind == "tcp":
            if self.tcp_holder is not None and not self.tcp_holder.closed:
                s.denied = True
            else:
                self.tcp_holder = s
        self.sessions.append(s)
        return s

    def close(self, s: Session) -> bool:
        """Forget ``s`` and what waits for it; True if it held the command interface."""
        s.closed = True
        s.subscriptions.clear()
        if s in self.sessions:
            self.sessions.remove(s)
        self.outbox = [(x, f) for x, f in self.outbox if x is not s]
        if self.tcp_holder is s:
            self.tcp_holder = None
            return True
        return False

    def emit(self, s: Session | None, frame: Frame) -> None:
        """Queue a deferred frame (final reply, power-up done) for ``s``."""
        if s is not None and not s.closed:
            self.outbox.append((s, frame))
            self.schedule.due_valid = False

    def take(self, s: Session) -> list[Frame]:
        """The queued frames of ``s`` (removed from the outbox)."""
        mine = [f for x, f in self.outbox if x is s]
        if mine:
            self.outbox = [(x, f) for x, f in self.outbox if x is not s]
        return mine

    # ------------------------------------------------------------------ auto-update

    def value_frame(self, cid: int, value: float | int) -> Frame:
        """The E_SUCCESS reply of 40h/41h/43h–45h carrying ``value``."""
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

    def request(self, s: Session, payload: bytes, now: float, cid: int) -> Frame:
        """40h/41h/43h–45h: the value now, and (FLAGS D0) subscribe or (D0 clear) unsubscribe."""
        flags, period_ms = _AUTO.unpack(payload)
        value = self.value_for(cid, now)
        if flags & _AUTO_UPDATE:
            if period_ms < MIN_PERIOD_MS:
                return Frame.reply(cid, Status.E_INVALID_PARAMETER)
            period = period_ms / 1000.0
            s.subscriptions[cid] = Subscription(cid, period, bool(flags & _CHANGE_ONLY),
                                                now + period, value, self.schedule.version)
            self.schedule.due_valid = False
        elif s.subscriptions:
            s.subscriptions.pop(cid, None)
        return self.value_frame(cid, value)

    def run(self, now: float) -> None:
        """Queue every auto-update packet due at ``now``."""
        moving = self.moving(now)
        version = self.schedule.version
        outbox = self.outbox
        value_for = self.value_for
        value_frame = self.value_frame
        for s in self.sessions:
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

    def next_due(self, now: float, due: float | None) -> float | None:
        """The earlier of ``due`` and the next queued frame or subscription that has work to do."""
        if self.outbox:
            due = now if due is None else min(due, now)
        moving = self.moving(now)
        version = self.schedule.version
        for s in self.sessions:
            for sub in s.subscriptions.values():
                if not sub.change_only or moving or sub.checked_version != version:
                    t = sub.next_time
                    due = t if due is None or t < due else due
        return due


def _changed(cid: int, old: float | int | None, new: float | int) -> bool:
    if old is None:
        return True
    threshold = CHANGE_THRESHOLDS.get(cid)
    if threshold is None:
        return old != new
    return abs(float(new) - float(old)) >= threshold - 1e-9
