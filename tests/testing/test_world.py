"""The world API's conventions, checked against the command set (000 §3.6, Appendix B)."""

from __future__ import annotations

import pytest

from pywsg.device import ManualClock, VirtualGripper
from pywsg.protocol import CATALOG, Command, Frame, Status
from pywsg.testing.world import WorldError, apply


def _finger_flags(g: VirtualGripper, cid: Command) -> int:
    s = g.open_session("udp", peer="test")
    (reply,) = g.handle_frame(s, Frame(int(cid), b""))
    status, values = CATALOG[cid].decode_reply(reply.payload)
    assert status == Status.E_SUCCESS
    return int(values["flags"])  # type: ignore[call-overload]


def test_fingers_are_numbered_1_and_2_as_in_the_manual() -> None:
    """000 §3.6.2 "Get Finger 1 Flags (61h)" / §3.6.6 "Get Finger 2 Flags (71h)": finger 2 is 71h's."""
    g = VirtualGripper("wsg50", clock=ManualClock())
    assert _finger_flags(g, Command.GET_FINGER1_FLAGS) == _finger_flags(g, Command.GET_FINGER2_FLAGS)
    assert apply(g, "fault", {"kind": "finger", "finger": 2}) == "finger 2 fault on"
    assert _finger_flags(g, Command.GET_FINGER2_FLAGS) != _finger_flags(g, Command.GET_FINGER1_FLAGS)
    assert g.fingers[1].fault and not g.fingers[0].fault
    with pytest.raises(WorldError, match="1 or 2"):
        apply(g, "fault", {"kind": "finger", "finger": 0})
