"""A throwaway stand-in for pywsg.device.VirtualGripper, used only until the real one lands.

Loop echo, 41h with auto-update, 21h as a 50 ms motion (pending, then final), 07h, E_CMD_UNKNOWN.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

from pywsg.protocol import ChecksumMismatch, Frame, FrameParser, FrameTooLarge, Status, parse_datagram
from pywsg.protocol.catalog import request_max_payload


class StandinSession:
    def __init__(self, kind: str, peer: str, deliver: Callable[[Frame], None] | None) -> None:
        self.kind, self.peer, self.deliver = kind, peer, deliver
        self.parser = FrameParser(True, request_max_payload)
        self.subs: dict[int, tuple[float, float]] = {}  # id -> (period, next due)
        self.announced = False


class StandinGripper:
    def __init__(self, model: str = "wsg50", settings: Any = None, clock: Any = None) -> None:
        self.clock = clock or time.monotonic
        self.sessions: list[StandinSession] = []
        self.motion: tuple[StandinSession, float] | None = None
        self.fast_stop = False
        self._listeners: list[Callable[[], None]] = []

    def open_session(self, kind: str, peer: str = "", deliver: Any = None) -> StandinSession:
        s = StandinSession(kind, peer, deliver)
        self.sessions.append(s)
        return s

    def close_session(self, s: StandinSession) -> None:
        if s in self.sessions:
            self.sessions.remove(s)
            if s.kind == "tcp" and not s.announced:
                self.fast_stop = True

    def feed(self, s: StandinSession, data: bytes) -> list[Frame]:
        out: list[Frame] = []
        for ev in s.parser.feed(data):
            if isinstance(ev, Frame):
                out += self.handle_frame(s, ev)
            elif isinstance(ev, ChecksumMismatch):
                out.append(Frame.reply(ev.command_id, Status.E_CHECKSUM_ERROR))
            elif isinstance(ev, FrameTooLarge):
                out.append(Frame.reply(ev.command_id, Status.E_CMD_FORMAT_ERROR))
        return out

    def handle_datagram(self, s: StandinSession, data: bytes) -> list[Frame]:
        out: list[Frame] = []
        for ev in parse_datagram(data, True, request_max_payload):
            if isinstance(ev, Frame):
                out += self.handle_frame(s, ev)
            elif isinstance(ev, ChecksumMismatch):
                out.append(Frame.reply(ev.command_id, Status.E_CHECKSUM_ERROR))
        return out

    def handle_frame(self, s: StandinSession, f: Frame) -> list[Frame]:
        cid = f.command_id
        if cid == 0x06:
            return [Frame.reply(cid, 0, f.payload)]
        if cid == 0x07:
            s.announced = True
            return [Frame.reply(cid, 0)]
        if cid == 0x41:
            if len(f.payload) == 3 and f.payload[0] & 1:
                period = max(int.from_bytes(f.payload[1:3], "little"), 10) / 1000
                s.subs[cid] = (period, self.clock() + period)
                self._wake()
            elif len(f.payload) == 3:
                s.subs.pop(cid, None)
            return [Frame.reply(cid, 0, b"\x00")]
        if cid == 0x21:
            if self.motion is not None:
                return [Frame.reply(cid, Status.E_ALREADY_RUNNING)]
            self.motion = (s, self.clock() + 0.05)
            self._wake()
            return [Frame.reply(cid, Status.E_CMD_PENDING)]
        return [Frame.reply(cid, Status.E_CMD_UNKNOWN)]

    def _wake(self) -> None:
        for fn in self._listeners:
            fn()

    def add_wakeup_listener(self, fn: Callable[[], None]) -> None:
        self._listeners.append(fn)

    def next_due(self) -> float | None:
        dues = [d for s in self.sessions for _, d in s.subs.values()]
        if self.motion:
            dues.append(self.motion[1])
        return min(dues) if dues else None

    def poll(self) -> list[tuple[StandinSession, Frame]]:
        now = self.clock()
        out: list[tuple[StandinSession, Frame]] = []
        if self.motion and self.motion[1] <= now:
            out.append((self.motion[0], Frame.reply(0x21, 0)))
            self.motion = None
        for s in self.sessions:
            for cid, (period, due) in list(s.subs.items()):
                if due <= now:
                    out.append((s, Frame.reply(cid, 0, b"\x00")))
                    nxt = due + period
                    s.subs[cid] = (period, nxt if nxt > now else now + period)
        for s, fr in out:
            if s.deliver:
                s.deliver(fr)
        return out
