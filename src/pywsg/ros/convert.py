"""Units and meanings between the WSG (mm, mm/s, N, gripper states, system flags) and ROS
(metres, REP 103; a goal's ``reached_goal`` / ``stalled``; diagnostic levels). Pure functions, no rclpy."""

from __future__ import annotations

from dataclasses import dataclass

from ..protocol import GripperState, SystemFlag

MM_PER_M = 1000.0

#: diagnostic_msgs/DiagnosticStatus levels
OK, WARN, ERROR, STALE = 0, 1, 2, 3

#: flags that make the gripper refuse motion until someone acts: ERROR
ERROR_FLAGS = (SystemFlag.SF_FAST_STOP | SystemFlag.SF_TEMP_FAULT | SystemFlag.SF_POWER_FAULT
               | SystemFlag.SF_CURR_FAULT | SystemFlag.SF_FINGER_FAULT)
#: flags worth a look that leave the gripper working: WARN
WARN_FLAGS = (SystemFlag.SF_TEMP_WARNING | SystemFlag.SF_CMD_FAILURE | SystemFlag.SF_SCRIPT_FAILURE)


def to_mm(metres: float) -> float:
    return metres * MM_PER_M


def to_m(mm: float) -> float:
    return mm / MM_PER_M


#: wsg50-ros-pkg's convention (its URDF expects it): the left finger's joint opens negative
MIRRORED = (-1.0, 1.0)


def finger_positions(width_mm: float, signs: tuple[float, float] = MIRRORED) -> tuple[float, float]:
    """Joint positions in metres of the two fingers (left, right) for an opening of ``width_mm``: each
    finger moves half the opening, times its sign (``(1, 1)`` for a URDF whose finger joints both open
    positive, as MoveIt's parallel-jaw gripper handle sums them)."""
    half = width_mm / 2 / MM_PER_M
    return signs[0] * half, signs[1] * half


def finger_velocities(speed_mm_s: float, signs: tuple[float, float] = MIRRORED) -> tuple[float, float]:
    """Joint velocities in m/s for an opening speed of ``speed_mm_s`` (signed as the positions)."""
    half = speed_mm_s / 2 / MM_PER_M
    return signs[0] * half, signs[1] * half


@dataclass(frozen=True)
class Outcome:
    """What a finished GripperCommand goal reports (control_msgs/action/GripperCommand result)."""

    succeeded: bool
    reached_goal: bool
    stalled: bool


def outcome(state: GripperState | int) -> Outcome:
    """A goal's result from the gripper state at its end (000 §3.4.2): HOLDING is stalled at the part
    (the goal succeeded, the fingers stopped short of the commanded gap); NO_PART and PART_LOST did not
    reach it (aborted); IDLE and RELEASING (a finished move or release) reached it."""
    if state == GripperState.HOLDING:
        return Outcome(True, False, True)
    if state in (GripperState.IDLE, GripperState.RELEASING):
        return Outcome(True, True, False)
    return Outcome(False, False, False)


def diagnostic_level(flags: SystemFlag | None) -> tuple[int, str]:
    """Level and one-line message of the gripper's diagnostic status from its system flags (000 §3.4.1);
    ``None``: not connected (STALE)."""
    if flags is None:
        return STALE, "not connected"
    bad = flags & ERROR_FLAGS
    if bad:
        return ERROR, ", ".join(flag_names(bad))
    warn = flags & WARN_FLAGS
    if warn:
        return WARN, ", ".join(flag_names(warn))
    if SystemFlag.SF_REFERENCED not in flags:
        return WARN, "not referenced: call homing"
    return OK, "ready"


def flag_names(flags: SystemFlag) -> list[str]:
    """The names of the set flags, lowest bit first (``["SF_REFERENCED", "SF_FAST_STOP"]``)."""
    return [f.name for f in SystemFlag if f.value and f in flags and f.name is not None]


def state_name(state: GripperState | int | None) -> str:
    """``HOLDING``, or the number of a state the manual does not name, or ``UNKNOWN``."""
    if state is None:
        return "UNKNOWN"
    return state.name if isinstance(state, GripperState) and state.name else str(int(state))
