"""The facade's listener API: command listeners (before a request runs) and gripper-state listeners
(every change of the 41h state, 000 §3.4.2), on the manual clock."""

from __future__ import annotations

from pywsg.device import Session
from pywsg.protocol import Command, GripperState, Status

from .devrig import Rig

GS = GripperState


def test_command_listener_runs_before_the_request(homed: Rig) -> None:
    """A part placed by the listener before 25h Grip Part is there for the grip (000 §3.2.6: HOLDING)."""
    seen: list[tuple[Session, int]] = []

    def on_command(session: Session, command_id: int) -> None:
        seen.append((session, command_id))
        if command_id == Command.GRIP_PART:
            homed.g.faults.place_part(22.0)

    homed.g.add_command_listener(on_command)
    assert homed.status(Command.GRIP_PART, width=22.0, speed=100.0) == Status.E_CMD_PENDING
    homed.run(2.0)
    assert seen == [(homed.s, int(Command.GRIP_PART))]
    assert homed.g.snapshot().gripper_state == GS.HOLDING

    homed.g.remove_command_listener(on_command)
    homed.gstate()                                   # 41h: heard no more
    assert len(seen) == 1


def test_command_listener_does_not_hear_a_refused_client(homed: Rig) -> None:
    """A second TCP client is answered E_ACCESS_DENIED and changes nothing (docs/fidelity.md)."""
    seen: list[int] = []
    homed.g.add_command_listener(lambda s, cid: seen.append(cid))
    second = homed.g.open_session("tcp", peer="second")
    assert homed.send(Command.STOP, session=second)[-1].status == Status.E_ACCESS_DENIED
    assert seen == []
    homed.status(Command.STOP)
    assert seen == [int(Command.STOP)]


def test_state_listener_hears_every_change_in_order(homed: Rig) -> None:
    """GRIPPING → HOLDING → PART_LOST (000 §3.4.2), even when HOLDING lasts no poll at all."""
    changes: list[tuple[GS, GS]] = []
    homed.g.add_state_listener(lambda old, new: changes.append((old, new)))
    homed.g.faults.place_part(22.0)
    homed.status(Command.GRIP_PART, width=22.0, speed=100.0)
    assert changes == [(GS.IDLE, GS.GRIPPING)]       # reported when handle_frame is done
    # no poll between the contact and the removal: both changes come with the next call
    homed.clock.advance(2.0)
    homed.g.faults.remove_part()
    homed.run(1.0)
    assert changes == [(GS.IDLE, GS.GRIPPING), (GS.GRIPPING, GS.HOLDING), (GS.HOLDING, GS.PART_LOST)]


def test_a_state_listener_may_act_on_the_device(homed: Rig) -> None:
    """A listener that removes the part on HOLDING: the PART_LOST it causes is reported next."""
    changes: list[GS] = []

    def on_state(old: GS, new: GS) -> None:
        changes.append(new)
        if new == GS.HOLDING:
            homed.g.faults.remove_part()

    homed.g.add_state_listener(on_state)
    homed.g.faults.place_part(22.0)
    homed.status(Command.GRIP_PART, width=22.0, speed=100.0)
    homed.run(2.0)
    assert changes == [GS.GRIPPING, GS.HOLDING, GS.PART_LOST]


def test_state_listener_hears_a_restart_and_can_be_removed(homed: Rig) -> None:
    changes: list[tuple[GS, GS]] = []

    def on_state(old: GS, new: GS) -> None:
        changes.append((old, new))

    homed.g.add_state_listener(on_state)
    homed.g.faults.place_part(22.0)
    homed.status(Command.GRIP_PART, width=22.0, speed=100.0)
    homed.run(2.0)
    homed.g.restart()
    homed.run(0.1)
    assert changes[-1] == (GS.HOLDING, GS.IDLE)
    homed.g.remove_state_listener(on_state)
    n = len(changes)
    homed.home()
    assert len(changes) == n
