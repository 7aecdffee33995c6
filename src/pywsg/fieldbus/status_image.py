"""The input image the controller shows the PLC (002 §3.2 input registers; 003 §4.1.2) and the gripper
state's rules: GSTATE computed on top of the device's state, and which command each state allows.

Gripper state (GSTATE) is the fieldbus manuals' own, so it holds whatever the binary protocol's 41h
reports (decisions in docs/fidelity.md):

- Preconditions (002 §4.1 / 003 §5.1 "MOVE can only be issued if the gripper is idle"; the others
  decided by analogy, table :data:`STARTS_FROM`): a motion edge in another state is refused and the
  motion in progress is left alone; STATUS = E_ALREADY_RUNNING while a motion runs, else
  E_ACCESS_DENIED.
- "In case of an error, the gripper state is set to ERROR" (002 §4.1–4.3, 003 §5.1–5.3): a MOVE,
  GRIP, RELEASE or HOMING whose final status is an error shows ERROR with that status until the
  next accepted command (a GRIP that finds no part is NO_PART / E_CMD_FAILED, as §4.2 says).
- FAST STOP: "The gripper state is set to IDLE" (002 §4.6, 003 §5.6), from any source, while the
  FAST STOP lasts and until the next accepted command or a motion started elsewhere.
- Jogging shows RELEASING (002 §4.7).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Protocol

from ..protocol import GripperState, Status, SystemFlag
from .device_session import GS, DeviceSession
from .image import JOG, CmdFlag, InputImage

#: Gripper states in which fingers move on a command; a new motion edge is refused (E_ALREADY_RUNNING).
RUNNING_STATES = frozenset({GS.GRIPPING, GS.RELEASING, GS.POSITIONING})

#: The gripper states each motion command may start from. MOVE: 002 §4.1 / 003 §5.1. The rest are
#: decisions (docs/fidelity.md): GRIP like MOVE from IDLE only; RELEASE also takes the part (or the
#: fingers after NO_PART / PART_LOST / ERROR) away; HOMING and jog are the ways out of a bad
#: position, refused only while a part is held.
STARTS_FROM: dict[CmdFlag, frozenset[GripperState]] = {
    CmdFlag.MOVE: frozenset({GS.IDLE}),
    CmdFlag.GRIP: frozenset({GS.IDLE}),
    CmdFlag.RELEASE: frozenset({GS.IDLE, GS.HOLDING, GS.NO_PART, GS.PART_LOST, GS.ERROR}),
    CmdFlag.HOMING: frozenset({GS.IDLE, GS.NO_PART, GS.PART_LOST, GS.ERROR}),
    JOG: frozenset({GS.IDLE, GS.NO_PART, GS.PART_LOST, GS.ERROR}),
}


class SnapshotLike(Protocol):
    width: float
    force: float
    gripper_state: GripperState
    flags: SystemFlag


@dataclass
class _State:
    width: float
    force: float
    gripper_state: GripperState
    flags: SystemFlag


class StatusImage(DeviceSession):
    """GSTATE, SYSSTATE, WIDTH, FORCE, STATUS CODE and OF as the PLC reads them; command preconditions."""

    @property
    def output_bytes(self) -> bytes:
        """The 8 output bytes last written by the PLC."""
        return self.output_image.pack()

    def input_image(self) -> InputImage:
        """The input image now (SYSSTATE, WIDTH, FORCE fresh on every call)."""
        snap = self._state()
        state = self._fieldbus_state(snap)
        if self._jog_dir and not self._jog_done:
            if snap.flags & SystemFlag.SF_MOVING:
                # 002 §4.7: the gripper state is RELEASING while jogging.
                if state == GripperState.POSITIONING:
                    state = GripperState.RELEASING
            else:
                # Jog reached an end position or an obstacle: report its result.
                self._jog_done = True
                self.status = int(Status.E_SUCCESS)
        of_flags = int(getattr(self.gripper, "script_of", 0)) & 0xFF
        return InputImage.from_state(state, SystemFlag(int(snap.flags)), float(snap.width),
                                     float(snap.force), self.status, of_flags, self.model)

    def gripper_state(self) -> GripperState:
        """GSTATE as the fieldbus shows it now (see the module docstring)."""
        return self.input_image().state or GS.IDLE

    def _fieldbus_state(self, snap: SnapshotLike) -> GripperState:
        device = GripperState(snap.gripper_state)
        if snap.flags & SystemFlag.SF_FAST_STOP:
            # 002 §4.6 / 003 §5.6: FAST STOP sets the gripper state to IDLE (the device's 41h may say
            # ERROR or HOLDING); it stays IDLE after the acknowledgement until the next command.
            self._shown, self._failed = GS.IDLE, None
        elif self._failed is not None:
            cmd, status = self._failed
            self._failed = None
            if cmd == CmdFlag.GRIP and device == GS.NO_PART:
                # 002 §4.2: "If no part was found, the status code is set to E_CMD_FAILED" (also when
                # the fingers ran into the end stop instead of through the clamping travel).
                self.status = int(Status.E_CMD_FAILED)
            else:
                self._shown = GS.ERROR
                self._emit(f"{cmd.name} failed ({Status.describe(status)}): gripper state ERROR")
        elif self._shown is not None and device in RUNNING_STATES and snap.flags & SystemFlag.SF_MOVING \
                and self._pending is None and not self._jog_dir:
            self._shown = None   # another interface started a motion: show it
        return device if self._shown is None else self._shown

    def _state(self) -> SnapshotLike:
        """The four values the input image needs; cheaper than a full snapshot on every bus read."""
        g: Any = self.gripper
        if all(hasattr(g, a) for a in ("width", "force", "system_flags", "gstate", "clock")):
            now = g.clock()
            return _State(float(g.width(now)), float(g.force(now)), GripperState(g.gstate),
                          SystemFlag(int(g.system_flags(now))))
        snap: SnapshotLike = self.gripper.snapshot()
        return snap

    def input_bytes(self) -> bytes:
        """The 12 input bytes now."""
        return self.input_image().pack()

    def _refused(self, cmd: CmdFlag) -> bool:
        """Check the command's precondition (:data:`STARTS_FROM`); if it fails, say so in STATUS."""
        state = GS.RELEASING if self._jog_dir and not self._jog_done else self.gripper_state()
        if state in STARTS_FROM[cmd]:
            return False
        status = Status.E_ALREADY_RUNNING if state in RUNNING_STATES else Status.E_ACCESS_DENIED
        name = "JOG" if cmd == JOG else cmd.name
        self._emit(f"{name} refused: gripper state {state.name} ({Status.describe(status)})")
        self._set_status(status)
        return True
