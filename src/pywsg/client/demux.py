"""Sans-IO demultiplexer: which incoming frame belongs to which outstanding call or stream.

The WSG protocol has no sequence numbers: a reply carries only the command ID. The rules here:

- Per command ID, immediate replies come back in request order (FIFO of waiters).
- A motion command answers E_CMD_PENDING, then one final frame with the same ID: the pending
  reply moves the call's *final* waiter into that ID's final queue before anyone else can see a
  later frame, so a final that arrives in the same read as the pending reply is never misrouted.
- When both an immediate reply and a final are outstanding for the same ID (a second motion sent
  while one runs) the status decides: E_CMD_PENDING / E_ALREADY_RUNNING and the immediate
  refusals answer the request, the motion-ending statuses (E_SUCCESS, E_CMD_ABORTED, E_CMD_FAILED,
  E_AXIS_BLOCKED, E_TIMEOUT) complete the running motion.
- Auto-update packets (40h/41h/43h/44h/45h, always E_SUCCESS) go to that ID's streams. Such a
  frame is indistinguishable from the reply to an explicit read of the same ID, so while a read is
  outstanding the first E_SUCCESS frame of that ID answers it *and* is also given to the streams
  (it is a current sample either way); nothing is dropped.
- A call that timed out leaves a "ghost" that swallows its late reply for a while, so the next
  call of that ID cannot receive a stale answer. When that reply never comes (a silent gripper, a
  lost datagram), the ghost swallows the next call's reply instead; that call, if it times out too,
  leaves no ghost of its own (its reply is the one already taken), so one lost reply costs at most one
  more timeout instead of a chain of them.
"""

from __future__ import annotations

import logging
from collections import deque
from collections.abc import Callable

from ..protocol import ChecksumMismatch, Command, Frame, Status

log = logging.getLogger("pywsg.client")

# statuses with which a running motion ends (its final frame)
FINAL_STATUSES = frozenset({Status.E_SUCCESS, Status.E_CMD_ABORTED, Status.E_CMD_FAILED, Status.E_AXIS_BLOCKED,
                            Status.E_TIMEOUT})
GHOST_TTL = 5.0  # s a late reply of a timed-out call is still expected


class Waiter:
    """One expected frame. Shells subclass it and override :meth:`_wake`."""

    __slots__ = ("command_id", "done", "error", "final", "frame", "ghost_until", "robbed")

    def __init__(self, command_id: int, final: Waiter | None = None) -> None:
        self.command_id = command_id
        self.frame: Frame | None = None
        self.error: BaseException | None = None
        self.done = False
        self.ghost_until = 0.0  # > 0: abandoned (timed out) until this monotonic time
        self.final = final  # moved to the final queue if the reply is E_CMD_PENDING
        self.robbed = False  # a ghost ahead of it swallowed a frame while it waited (maybe its reply)

    def resolve(self, frame: Frame) -> None:
        if not self.done:
            self.frame = frame
            self.done = True
            self._wake()

    def fail(self, exc: BaseException) -> None:
        if not self.done:
            self.error = exc
            self.done = True
            self._wake()

    def _wake(self) -> None:
        pass


class Sink:
    """A stream's receiving end, for one auto-update ``command``. Shells subclass it."""

    command: Command

    def push(self, frame: Frame) -> None:
        raise NotImplementedError

    def end(self, exc: BaseException | None) -> None:
        raise NotImplementedError

    def revive(self) -> None:
        """The connection is back (reconnect): accept samples again."""


def _status(frame: Frame) -> int:
    p = frame.payload
    return p[0] | (p[1] << 8) if len(p) >= 2 else -1


class Demux:
    """Routes frames to waiters and streams. Not thread-safe: the shell serialises calls."""

    def __init__(self, clock: Callable[[], float]) -> None:
        self.clock = clock
        self.replies: dict[int, deque[Waiter]] = {}
        self.finals: dict[int, deque[Waiter]] = {}
        self.streams: dict[int, list[Sink]] = {}
        self.unsolicited = 0  # frames nobody expected
        self.late = 0  # late replies swallowed by ghosts
        self.on_unsolicited: Callable[[Frame], None] | None = None

    # -- registration
    def expect(self, waiter: Waiter) -> None:
        q = self.replies.get(waiter.command_id)
        if q is None:
            q = self.replies[waiter.command_id] = deque()
        q.append(waiter)

    def expect_first(self, waiter: Waiter) -> None:
        """Register a waiter whose request went out before those of every waiter queued for its ID
        (a call that waited without a waiter while it was alone, see ``Gripper._exchange_immediate``)."""
        q = self.replies.get(waiter.command_id)
        if q is None:
            q = self.replies[waiter.command_id] = deque()
        q.appendleft(waiter)

    def alone(self, command_id: int) -> bool:
        """Nothing expected on this ID: no reply (nor ghost), no motion final, no stream."""
        return not self.replies.get(command_id) and not self.finals.get(command_id) and command_id not in self.streams

    def abandon(self, waiter: Waiter) -> None:
        """The call gave up waiting: keep a ghost for its late reply (if still queued) — unless a ghost
        ahead of it already swallowed a frame meanwhile: that was its reply (module docstring)."""
        waiter.done = True
        if waiter.robbed:
            q = self.replies.get(waiter.command_id)
            if q is not None and waiter in q:
                q.remove(waiter)
            return
        waiter.ghost_until = self.clock() + GHOST_TTL

    def forget_final(self, waiter: Waiter) -> None:
        q = self.finals.get(waiter.command_id)
        if q is not None and waiter in q:
            q.remove(waiter)

    def add_stream(self, command_id: int, sink: Sink) -> None:
        self.streams.setdefault(command_id, []).append(sink)

    def remove_stream(self, command_id: int, sink: Sink) -> None:
        sinks = self.streams.get(command_id)
        if sinks and sink in sinks:
            sinks.remove(sink)
            if not sinks:
                del self.streams[command_id]

    def outstanding(self) -> int:
        return sum(1 for q in self.replies.values() for w in q if not w.ghost_until) + sum(
            len(q) for q in self.finals.values()
        )

    # -- routing
    def _pop_reply(self, cid: int) -> Waiter | None:
        q = self.replies.get(cid)
        while q:
            w = q.popleft()
            if w.ghost_until:
                if w.ghost_until >= self.clock():
                    return w  # swallows this (late) frame
                continue  # expired ghost: its reply was lost
            return w
        return None

    def _has_reply(self, cid: int) -> bool:
        q = self.replies.get(cid)
        return bool(q)

    def feed(self, frame: Frame) -> None:
        cid = frame.command_id
        q = self.replies.get(cid)
        if q and cid not in self.streams and not self.finals.get(cid):
            # the common case: one call waits for this ID, no stream, no running motion
            head = q[0]
            if not head.ghost_until and (head.final is None or _status(frame) != Status.E_CMD_PENDING):
                q.popleft()
                head.resolve(frame)
                return
        status = _status(frame)
        sinks = self.streams.get(cid)
        if sinks and status == Status.E_SUCCESS:
            for s in tuple(sinks):
                s.push(frame)
            w = self._pop_reply(cid)
            if w is not None:
                self._deliver(w, frame, status)
            return
        finals = self.finals.get(cid)
        if finals and (not self._has_reply(cid) or status in FINAL_STATUSES):
            finals.popleft().resolve(frame)
            return
        w = self._pop_reply(cid)
        if w is not None:
            self._deliver(w, frame, status)
            return
        self.unsolicited += 1
        log.debug("unsolicited frame %02Xh (status %d) dropped", cid, status)
        if self.on_unsolicited is not None:
            self.on_unsolicited(frame)

    def _deliver(self, w: Waiter, frame: Frame, status: int) -> None:
        if w.ghost_until:
            self.late += 1
            log.debug("late reply %02Xh after a timeout swallowed", frame.command_id)
            q = self.replies.get(frame.command_id)
            if q and not q[0].ghost_until:
                q[0].robbed = True
            if status == Status.E_CMD_PENDING and w.final is not None:
                w.final.ghost_until = w.ghost_until
                self.finals.setdefault(frame.command_id, deque()).append(w.final)
            return
        if status == Status.E_CMD_PENDING and w.final is not None:
            self.finals.setdefault(frame.command_id, deque()).append(w.final)
        w.resolve(frame)

    def feed_bad_checksum(self, event: ChecksumMismatch, exc_factory: Callable[[int], BaseException]) -> bool:
        """A frame with a bad CRC: fail the call waiting for that ID (never accept the frame).

        Returns False when nobody waited for that ID (the frame is dropped and logged)."""
        cid = event.command_id
        w = self._pop_reply(cid)
        if w is None:
            finals = self.finals.get(cid)
            if finals:
                w = finals.popleft()
        if w is None or w.ghost_until:
            log.warning("dropped a frame %02Xh with a bad checksum (nobody waiting for it)", cid)
            return False
        w.fail(exc_factory(cid))
        return True

    def fail_all(self, exc_factory: Callable[[int], BaseException]) -> None:
        """Connection lost: fail every waiting call at once (streams are the shell's business)."""
        for queues in (self.replies, self.finals):
            for q in queues.values():
                while q:
                    w = q.popleft()
                    if not w.ghost_until:
                        w.fail(exc_factory(w.command_id))
            queues.clear()
