"""Test rig for the virtual gripper: a gripper on a ManualClock and a client session."""

from __future__ import annotations

from dataclasses import dataclass, field

from pywsg.device import ManualClock, Session, Settings, VirtualGripper
from pywsg.protocol import CATALOG, Frame, Status, Value


@dataclass
class Rig:
    """A gripper, its clock and one TCP session, with helpers that speak frames."""

    clock: ManualClock
    g: VirtualGripper
    s: Session
    deferred: list[Frame] = field(default_factory=list)

    def send(self, cid: int, payload: bytes | None = None, session: Session | None = None,
             **values: Value) -> list[Frame]:
        """Send one request frame (payload from the catalog unless given); returns immediate replies."""
        if payload is None:
            payload = CATALOG[cid].encode_request(**values) if cid in CATALOG else b""
        return self.g.handle_frame(session or self.s, Frame(cid, payload))

    def call(self, cid: int, payload: bytes | None = None, **values: Value) -> Frame:
        """Send and return the command's immediate reply (earlier due frames go to ``deferred``)."""
        replies = self.send(cid, payload, **values)
        assert replies and replies[-1].command_id == cid, replies
        self.deferred.extend(replies[:-1])
        return replies[-1]

    def status(self, cid: int, payload: bytes | None = None, **values: Value) -> Status | int:
        return self.call(cid, payload, **values).status

    def value(self, cid: int, **values: Value) -> dict[str, Value]:
        reply = self.call(cid, **values)
        status, decoded = CATALOG[cid].decode_reply(reply.payload)
        assert status == Status.E_SUCCESS, status
        return decoded

    def run(self, dt: float, step: float | None = None) -> list[Frame]:
        """Advance the clock by ``dt`` s, polling at every due time (like the server's runner)."""
        end = self.clock.now + dt
        out: list[Frame] = []
        while True:
            due = self.g.next_due()
            if step is not None:
                nxt = self.clock.now + step
                due = nxt if due is None else min(due, nxt)
            if due is None or due > end:
                break
            self.clock.set(max(due, self.clock.now))
            got = [f for s, f in self.g.poll() if s is self.s]
            out.extend(got)
            if step is None and not got and self.g.next_due() == due:
                break  # pragma: no cover - would spin
        self.clock.set(end)
        out.extend(f for s, f in self.g.poll() if s is self.s)
        self.deferred.extend(out)
        return out

    def finals(self, dt: float = 10.0) -> list[Frame]:
        return self.run(dt)

    def home(self) -> None:
        assert self.status(0x20, direction=0) == Status.E_CMD_PENDING
        out = self.run(5.0)
        assert [f.status for f in out if f.command_id == 0x20] == [Status.E_SUCCESS]

    def width(self) -> float:
        return float(self.value(0x43, flags=0, period_ms=0)["width"])  # type: ignore[arg-type]

    def gstate(self) -> int:
        return int(self.value(0x41, flags=0, period_ms=0)["state"])  # type: ignore[call-overload]

    def flags(self) -> int:
        return int(self.value(0x40, flags=0, period_ms=0)["state"])  # type: ignore[call-overload]


def make_rig(model: str | None = None, settings: Settings | None = None, kind: str = "tcp") -> Rig:
    clock = ManualClock()
    g = VirtualGripper(model, settings=settings, clock=clock)
    return Rig(clock, g, g.open_session(kind, peer="127.0.0.1:5555"))


