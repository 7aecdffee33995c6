"""A reply that never comes (silent gripper, lost datagram) costs at most one more timeout (client/demux.py):
the timed-out call's ghost takes the next call's reply, and that call leaves no ghost of its own."""

from __future__ import annotations

from pywsg.client.demux import Demux, Waiter
from pywsg.protocol import Command, Frame, Status


def _reply(data: bytes) -> Frame:
    return Frame.reply(Command.LOOP, Status.E_SUCCESS, data)


def test_a_lost_reply_costs_one_more_timeout_not_a_chain() -> None:
    now = [0.0]
    d = Demux(lambda: now[0])
    lost = Waiter(Command.LOOP)
    d.expect(lost)
    d.abandon(lost)  # timed out: its reply never comes
    second = Waiter(Command.LOOP)
    d.expect(second)
    d.feed(_reply(b"2"))  # the second call's reply: the ghost takes it (it cannot know)
    assert not second.done and d.late == 1
    d.abandon(second)  # the second call times out too ...
    third = Waiter(Command.LOOP)
    d.expect(third)
    d.feed(_reply(b"3"))
    assert third.done and third.frame is not None and third.frame.payload[2:] == b"3"  # ... and no ghost ate this


def test_a_late_reply_is_still_swallowed_by_its_ghost() -> None:
    now = [0.0]
    d = Demux(lambda: now[0])
    slow = Waiter(Command.LOOP)
    d.expect(slow)
    d.abandon(slow)
    nxt = Waiter(Command.LOOP)
    d.expect(nxt)
    d.feed(_reply(b"stale"))  # the timed-out call's reply, late
    assert not nxt.done
    d.feed(_reply(b"fresh"))  # then the next call's own reply
    assert nxt.done and nxt.frame is not None and nxt.frame.payload[2:] == b"fresh"
