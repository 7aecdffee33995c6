"""A held part, a lost part and the end of jog, in raw frames on the manual clock (issue 24 items 1-3, 7).

- 000 §3.2.2 FLAGS D1: "If a blocking condition towards the movement direction of the fingers is
  detected, the motion command returns an E_AXIS_BLOCKED error and the motor is stopped." A held part
  is such a condition for every motion towards it: 21h E_AXIS_BLOCKED, 26h the blocked release
  (000 §3.2.7 lists only E_TIMEOUT), 20h the wrong reference (000 §3.2.1).
- 000 §3.4.2 PART_LOST: "This state will persist until the next Grip Part, Release Part or Pre-position
  Fingers command is issued": those three are accepted at once.
- 002 §4.7 / 003 §5.7: "If the Jog flags change to both 0, the Jog mode is left and the drive is stopped."
"""

from __future__ import annotations

import struct

import pytest

from pywsg.protocol import Frame, GripperState, Status, SystemFlag

from .devrig import Rig

S = Status
GS = GripperState
SF = SystemFlag
STOP_ON_BLOCK = 0x02  # 21h FLAGS D1
CLAMP_ON_BLOCK = 0x00


def _frame(cid: int, payload: bytes) -> bytes:
    return Frame(cid, payload).encode()


def _raw(rig: Rig, data: bytes) -> list[Frame]:
    """Feed raw bytes as a TCP client sends them; the immediate replies."""
    return rig.g.feed(rig.s, data)


def _prepos(flags: int, width: float, speed: float = 50.0) -> bytes:
    return _frame(0x21, struct.pack("<Bff", flags, width, speed))


def _finals(rig: Rig, cid: int, dt: float = 5.0) -> list[int]:
    return [int(f.status) for f in rig.run(dt) if f.command_id == cid]


def _hold(rig: Rig, width: float = 30.0, **part: float | bool) -> None:
    rig.home()
    rig.g.faults.place_part(width, **part)  # type: ignore[arg-type]
    (reply,) = _raw(rig, _frame(0x25, struct.pack("<ff", width, 50.0)))
    assert reply.status == S.E_CMD_PENDING
    assert _finals(rig, 0x25) == [S.E_SUCCESS]
    assert rig.gstate() == GS.HOLDING


# ---------------------------------------------------------------- item 1: a held part blocks


def test_a_held_part_reads_its_own_width(homed: Rig) -> None:
    """000 §3.2.6: HOLDING at the part; the default part is rigid, so 43h reads its width exactly."""
    homed.g.faults.place_part(30.0)
    homed.call(0x25, struct.pack("<ff", 30.0, 50.0))
    homed.run(5)
    assert homed.gstate() == GS.HOLDING and homed.width() == 30.0


@pytest.mark.parametrize(("flags", "force"), [(STOP_ON_BLOCK, 0.0), (CLAMP_ON_BLOCK, 40.0)],
                         ids=["stop-on-block", "clamp-on-block"])
def test_preposition_into_a_held_part_is_blocked(rig: Rig, flags: int, force: float) -> None:
    """000 §3.2.2 FLAGS D1: 21h towards the held part answers pending, then E_AXIS_BLOCKED at once; the
    fingers stay at the part (30 mm, not 20); stop: the motor is stopped (45h 0 N); clamp: 50 % of the
    nominal force (40 N of 80 N). 41h ERROR, SF_BLOCKED_MINUS."""
    _hold(rig)
    (reply,) = _raw(rig, _prepos(flags, 20.0))
    assert reply.status == S.E_CMD_PENDING
    t0 = rig.clock.now
    out = rig.run(0.001)
    assert [f.status for f in out if f.command_id == 0x21] == [S.E_AXIS_BLOCKED]
    assert rig.clock.now - t0 <= 0.001
    assert rig.run(2.0) == []
    assert rig.width() == 30.0
    assert rig.gstate() == GS.ERROR
    assert rig.flags() & SF.SF_BLOCKED_MINUS
    assert float(rig.value(0x45, flags=0, period_ms=0)["force"]) == pytest.approx(force)  # type: ignore[arg-type]


def test_release_towards_a_held_part_pushes_on_and_times_out(rig: Rig) -> None:
    """000 §3.2.7 lists E_TIMEOUT, no E_AXIS_BLOCKED, for 26h: towards the held part it is the blocked
    release (docs/fidelity.md): RELEASING, blocked at the part, then E_TIMEOUT and ERROR; never 20 mm."""
    _hold(rig)
    (reply,) = _raw(rig, _frame(0x26, struct.pack("<ff", 20.0, 50.0)))
    assert reply.status == S.E_CMD_PENDING
    rig.run(0.1)
    assert rig.gstate() == GS.RELEASING and rig.width() == 30.0 and rig.flags() & SF.SF_BLOCKED_MINUS
    assert _finals(rig, 0x26) == [S.E_TIMEOUT]
    assert rig.width() == 30.0 and rig.gstate() == GS.ERROR


def test_homing_into_a_held_part_takes_it_for_the_end_stop(rig: Rig) -> None:
    """000 §3.2.1 NOTE: "Obstacles … during homing may result in a wrong reference point": homing
    towards the held part (negative) stops at it; 43h then reads 0 mm where the fingers are at 30 mm."""
    _hold(rig)
    (reply,) = _raw(rig, _frame(0x20, b"\x02"))
    assert reply.status == S.E_CMD_PENDING
    assert _finals(rig, 0x20) == [S.E_SUCCESS]
    assert rig.width() == 0.0 and rig.g.true_width() == pytest.approx(30.0)
    assert rig.flags() & SF.SF_REFERENCED
    assert "wrong reference point" in rig.g.log.entries[-1].message


def test_a_squeezed_part_blocks_where_the_fingers_hold_it(rig: Rig) -> None:
    """A part placed with a stiffness is squeezed by force / stiffness (80 N / 400 N/mm = 0.2 mm); a 21h
    towards it is blocked there (000 §3.2.2 FLAGS D1), it does not pass through."""
    _hold(rig, stiffness=400.0)
    assert rig.width() == pytest.approx(29.8, abs=1e-5)
    _raw(rig, _prepos(STOP_ON_BLOCK, 20.0))
    assert _finals(rig, 0x21) == [S.E_AXIS_BLOCKED]
    assert rig.width() == pytest.approx(29.8, abs=1e-5)


def test_moving_away_from_a_held_part_is_free(rig: Rig) -> None:
    """Only motions *towards* the part are blocked: 21h to 60 mm leaves it (force 0) and arrives."""
    _hold(rig)
    _raw(rig, _prepos(STOP_ON_BLOCK, 60.0))
    assert _finals(rig, 0x21) == [S.E_SUCCESS]
    assert rig.width() == 60.0 and rig.gstate() == GS.IDLE and rig.g.force() == 0.0


def test_a_ring_held_from_inside_blocks_opening(rig: Rig) -> None:
    """The same for a part gripped from inside (``inside=True``): opening towards it is blocked."""
    rig.home()
    _raw(rig, _prepos(STOP_ON_BLOCK, 10.0))
    rig.run(5)
    rig.g.faults.place_part(40.0, inside=True)
    _raw(rig, _frame(0x25, struct.pack("<ff", 40.0, 50.0)))
    assert _finals(rig, 0x25) == [S.E_SUCCESS]
    _raw(rig, _prepos(STOP_ON_BLOCK, 90.0))
    assert _finals(rig, 0x21) == [S.E_AXIS_BLOCKED]
    assert rig.width() == 40.0 and rig.flags() & SF.SF_BLOCKED_PLUS


# ---------------------------------------------------------------- item 7: outside unless inside


def test_a_part_wider_than_the_opening_is_gripped_from_outside_by_default(homed: Rig) -> None:
    """A part is placed between the fingers (gripped from outside) unless it is placed ``inside=True``,
    whatever the fingers' width: with the fingers at 25 mm a 50 mm part is no ring; a grip opening to
    50 mm finds no part (000 §3.2.6 NO_PART, E_CMD_FAILED), closing from 110 mm onto it holds it."""
    _raw(homed, _prepos(STOP_ON_BLOCK, 25.0))
    homed.run(5)
    homed.g.faults.place_part(50.0)
    _raw(homed, _frame(0x25, struct.pack("<ff", 50.0, 50.0)))
    assert _finals(homed, 0x25) == [S.E_CMD_FAILED] and homed.gstate() == GS.NO_PART
    _raw(homed, _prepos(STOP_ON_BLOCK, 110.0))
    homed.run(5)
    _raw(homed, _frame(0x25, struct.pack("<ff", 50.0, 50.0)))
    assert _finals(homed, 0x25) == [S.E_SUCCESS] and homed.width() == 50.0


# ---------------------------------------------------------------- item 2: after PART_LOST


@pytest.mark.parametrize(("request_bytes", "final"), [
    (_prepos(STOP_ON_BLOCK, 60.0), S.E_SUCCESS),                  # Pre-position Fingers
    (_frame(0x26, struct.pack("<ff", 60.0, 50.0)), S.E_SUCCESS),   # Release Part
    (_frame(0x25, struct.pack("<ff", 30.0, 50.0)), S.E_CMD_FAILED),  # Grip Part: the part is gone
], ids=["21h", "26h", "25h"])
def test_after_part_lost_the_named_commands_are_accepted_at_once(rig: Rig, request_bytes: bytes,
                                                                 final: Status) -> None:
    """000 §3.4.2: PART_LOST "will persist until the next Grip Part, Release Part or Pre-position
    Fingers command is issued". Right after the loss the fingers are at rest (no SF_MOVING) and each of
    the three is accepted (E_CMD_PENDING, not E_ALREADY_RUNNING) and ends as it should."""
    _hold(rig)
    rig.g.faults.remove_part()
    assert rig.gstate() == GS.PART_LOST
    assert not rig.flags() & SF.SF_MOVING and rig.g.force() == 0.0
    (reply,) = _raw(rig, request_bytes)
    assert reply.encode()[:8] == bytes.fromhex("AAAAAA") + request_bytes[3:4] + bytes.fromhex("0200 1A00")
    assert _finals(rig, request_bytes[3]) == [final]
    assert rig.value(0x42, flags=0)["lost_part"] == 1


# ---------------------------------------------------------------- item 3: the end of jog


def test_jog_end_stops_the_drive_pressing_on_an_obstacle(homed: Rig) -> None:
    """002 §4.7 / 003 §5.7: both jog flags back to 0 → "the Jog mode is left and the drive is stopped":
    the pressing force (30 N) goes to 0 (45h), BLOCKED_MINUS clears (cleared by a stop, 000 App. B D2),
    41h IDLE; the obstacle stays."""
    homed.g.faults.block_at(50.0)
    assert homed.g.jog(-1, 100.0, 30.0) == S.E_SUCCESS
    homed.run(2)
    assert homed.g.force() == 30.0 and homed.flags() & SF.SF_BLOCKED_MINUS
    assert homed.g.jog(0, 0.0, 0.0) == S.E_SUCCESS
    assert float(homed.value(0x45, flags=0, period_ms=0)["force"]) == 0.0  # type: ignore[arg-type]
    assert not homed.flags() & (SF.SF_BLOCKED_MINUS | SF.SF_MOVING)
    assert homed.gstate() == GS.IDLE and homed.width() == 50.0
    homed.run(2)
    assert homed.g.force() == 0.0
