"""The world API's conventions, checked against the command set (000 §3.6, Appendix B)."""

from __future__ import annotations

import pytest

from pywsg.device import ManualClock, VirtualGripper
from pywsg.protocol import CATALOG, Command, Frame, Status
from pywsg.testing.world import WorldError, apply, world_state


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


def test_parts_are_gripped_from_outside_unless_placed_inside() -> None:
    """Issue 24 item 7 (000 §3.2.6: the grip's direction follows the part's side): ``part`` places a part
    between the fingers (gripped from outside) whatever their width; ``inside: true`` a ring gripped from
    inside. The state says which (``part_inside``); a non-boolean ``inside`` is refused, naming it."""
    g = VirtualGripper("wsg50", clock=ManualClock())  # fingers at 55 mm, not referenced
    assert apply(g, "part", {"width": 80.0}) == "part of 80 mm placed (outside, between the fingers)"
    assert g.obstacles["part"].blocks == -1 and world_state(g)["part_inside"] is False
    text = apply(g, "part", {"width": 20.0, "inside": True, "stiffness": 300})
    assert text == "part of 20 mm (300 N/mm) placed (inside, a ring gripped from inside)"
    assert g.obstacles["part"].blocks == 1 and world_state(g)["part_inside"] is True
    apply(g, "remove_part")
    assert world_state(g)["part_inside"] is None
    with pytest.raises(WorldError, match="inside") as err:
        apply(g, "part", {"width": 20.0, "inside": "yes"})
    assert err.value.field == "inside"
