"""Fault injection: parts, obstacles, heat, power/current/finger faults (``gripper.faults``).

Each fault shows up exactly as the manual describes it: system flags (Appendix B), gripper
states (41h), status codes of the commands affected, and a system log entry.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

DEFAULT_PART_STIFFNESS = math.inf  # N/mm: rigid, so a held part reads its own width (docs/fidelity.md)


@dataclass(frozen=True, slots=True)
class Obstacle:
    """Something the fingers cannot pass: a part between (or around) them, or a blocking object.

    ``width`` in mm; ``blocks`` is the motion it stops: -1 closing onto it from above (a part
    between the fingers), +1 opening onto it from below (a ring gripped from inside);
    ``stiffness`` in N/mm (inf: rigid).
    """

    kind: str  # "part" or "block"
    width: float
    blocks: int
    stiffness: float = math.inf


class FaultTarget(Protocol):
    """The part of the device that faults act on (the device core implements it)."""

    @property
    def obstacles(self) -> dict[str, Obstacle]: ...

    def true_width(self, now: float | None = None) -> float: ...

    def obstacles_changed(self) -> None: ...

    def heat(self, delta_c: float) -> None: ...

    def set_power_fault(self, on: bool) -> None: ...

    def set_current_fault(self, on: bool) -> None: ...

    def set_finger_fault(self, n: int, on: bool) -> None: ...


class Faults:
    """Injects faults into one virtual gripper."""

    def __init__(self, gripper: FaultTarget) -> None:
        self._g = gripper

    def _side(self, width: float, inside: bool | None) -> int:
        if inside is not None:
            return 1 if inside else -1
        # placed below the fingers' current width: they close onto it; above: they open onto it
        return -1 if width <= self._g.true_width() + 1e-9 else 1

    def place_part(self, width: float, stiffness: float = DEFAULT_PART_STIFFNESS, inside: bool = False) -> None:
        """Put a part of ``width`` mm in the gripper: by default between the fingers, gripped from outside
        (closing onto it); ``inside=True``: a ring around the fingers, gripped from inside (opening onto
        it). ``stiffness`` in N/mm: how far the fingers squeeze it (default rigid: the part's width)."""
        if not math.isfinite(width) or width < 0:
            raise ValueError("width: must be a finite, non-negative number of mm")
        if not stiffness > 0:
            raise ValueError("stiffness: must be positive (N/mm)")
        if not isinstance(inside, bool):
            raise ValueError("inside: must be true (a ring gripped from inside) or false (gripped from outside)")
        self._g.obstacles["part"] = Obstacle("part", float(width), 1 if inside else -1, stiffness)
        self._g.obstacles_changed()

    def remove_part(self) -> None:
        """Take the part away (while HOLDING: the part is lost)."""
        if self._g.obstacles.pop("part", None) is not None:
            self._g.obstacles_changed()

    def block_at(self, width: float, inside: bool | None = None) -> None:
        """Put a rigid obstacle in the fingers' way at ``width`` mm."""
        if not math.isfinite(width) or width < 0:
            raise ValueError("width: must be a finite, non-negative number of mm")
        self._g.obstacles["block"] = Obstacle("block", float(width), self._side(width, inside))
        self._g.obstacles_changed()

    def unblock(self) -> None:
        """Remove the obstacle (a clamping pre-position then snaps to its target)."""
        if self._g.obstacles.pop("block", None) is not None:
            self._g.obstacles_changed()

    def heat(self, delta_c: float) -> None:
        """Raise the temperature by ``delta_c`` °C at once (it then relaxes to equilibrium)."""
        self._g.heat(delta_c)

    def power_fault(self, on: bool = True) -> None:
        """Supply voltage out of range: SF_POWER_FAULT and FAST STOP (ack refused while on)."""
        self._g.set_power_fault(on)

    def current_fault(self, on: bool = True) -> None:
        """Motor at its thermal current limit: SF_CURR_FAULT and FAST STOP (ack refused while on)."""
        self._g.set_current_fault(on)

    def finger_fault(self, n: int, on: bool = True) -> None:
        """Over-current on finger ``n`` (0 or 1): POWER_FAULT finger flag, SF_FINGER_FAULT,
        power switched off, data reads give E_IO_ERROR, power-on gives E_CMD_FAILED."""
        if n not in (0, 1):
            raise ValueError("n: finger index must be 0 or 1")
        self._g.set_finger_fault(n, on)
