"""The output image's commands (002 §4.1–4.6, 003 §5.1–5.6): MOVE, GRIP, RELEASE, HOMING, STOP/ACK and
FAST STOP, fired by the edges of CMDFLAGS (002 §3.1 output registers).

- A command fires on a 0→1 edge of its CMDFLAGS bit; if several rise in one update the lowest bit
  wins. A rising FASTSTOP is never lost: it is executed even when a lower bit rises with it.
- While FASTSTOP or STOP/ACK is held at 1, motion commands are not started (STATUS = E_ACCESS_DENIED).
- STOP/ACK stops a motion (22h), or acknowledges a FAST STOP (24h "ack", then 22h so the gripper
  state is IDLE) — only once FASTSTOP has been reset to 0, else STATUS = E_ACCESS_DENIED.
- A parameter beyond the system limits used by a motion command raises FAST STOP (STATUS =
  E_RANGE_ERROR); changing WIDTH/SPEED/FORCELIMIT while SF_MOVING (not jogging) raises FAST STOP
  (STATUS = E_CMD_ABORTED). MOVE stops on a block (21h flag STOP_ON_BLOCK) instead of clamping on.
- IF is copied to the gripper's script flags on every update.
"""

from __future__ import annotations

from typing import Any

from ..protocol import Command, GripperState, PrepositionFlag, Status, SystemFlag
from .image import MOTION_COMMANDS, CmdFlag, OutputImage
from .jog import Jog


class OutputCommands(Jog):
    """Applies each new output image: edges, jog levels, FAST STOP rules."""

    def write_outputs(self, image: OutputImage) -> None:
        """Apply a new output image: edges, jog levels, FAST STOP rules."""
        old, new = self.output_image, image
        self.output_image = new
        if new.if_flags != old.if_flags:
            self._set_script_if(new.if_flags)
        rising = CmdFlag(int(new.cmdflags) & ~int(old.cmdflags) & 0x3F)
        params_changed = (new.width, new.speed, new.force_limit) != (old.width, old.speed, old.force_limit)
        held = new.cmdflags & (CmdFlag.STOP_ACK | CmdFlag.FASTSTOP)

        if params_changed and not self._jog_dir:
            snap = self.gripper.snapshot()
            if snap.flags & SystemFlag.SF_MOVING:
                self._raise_fast_stop("parameter changed while MOVING", Status.E_CMD_ABORTED)
                self._update_jog(new, blocked=True)
                return

        if rising & CmdFlag.FASTSTOP:
            # Safety first: a FASTSTOP edge is executed even if a lower bit rose with it.
            self._raise_fast_stop("FASTSTOP flag", Status.E_SUCCESS)
        elif rising:
            lowest = CmdFlag(int(rising) & -int(rising))
            if lowest == CmdFlag.STOP_ACK:
                self._stop_ack(new)
            elif lowest & MOTION_COMMANDS:
                if held:
                    self._emit(f"{lowest.name} ignored: STOP/ACK or FASTSTOP held at 1")
                    self._set_status(Status.E_ACCESS_DENIED)
                elif self._refused(lowest):
                    pass
                else:
                    self._motion(lowest, new)
        self._update_jog(new, blocked=bool(held))

    def _set_script_if(self, flags: int) -> None:
        set_if = getattr(self.gripper, "set_script_if", None)
        if set_if is not None:
            set_if(flags)   # running scripts are told
        else:
            setattr(self.gripper, "script_if", flags)  # noqa: B010

    def _motion(self, cmd: CmdFlag, out: OutputImage) -> None:
        width, speed, force = out.width / 100, out.speed / 100, out.force_limit / self.force_scale
        lim = self.limits
        max_force = self._max_force()
        problem = None
        if cmd in (CmdFlag.MOVE, CmdFlag.GRIP, CmdFlag.RELEASE):
            if not 0 <= width <= lim.stroke:
                problem = f"WIDTH {width:.2f} mm outside 0..{lim.stroke:g} mm"
            elif not lim.min_speed <= speed <= lim.max_speed:
                problem = f"SPEED {speed:.2f} mm/s outside {lim.min_speed:g}..{lim.max_speed:g} mm/s"
        if problem is None and cmd == CmdFlag.GRIP and not lim.min_force <= force <= max_force:
            problem = f"FORCELIMIT {force:g} N outside {lim.min_force:g}..{max_force:g} N"
        if problem is None and cmd == CmdFlag.MOVE and out.force_limit and \
                not lim.min_force <= force <= max_force:
            problem = f"FORCELIMIT {force:g} N outside {lim.min_force:g}..{max_force:g} N"
        if problem is not None:
            self._raise_fast_stop(f"{cmd.name}: {problem}", Status.E_RANGE_ERROR)
            return

        frames: list[tuple[Command, dict[str, Any]]] = []
        if cmd == CmdFlag.HOMING:
            frames.append((Command.HOMING, {"direction": 0}))
        elif cmd == CmdFlag.MOVE:
            if out.force_limit:
                frames.append((Command.SET_FORCE_LIMIT, {"force": force}))
            # Stop on a block: a MOVE into an obstacle ends (E_AXIS_BLOCKED → ERROR) instead of
            # clamping on in POSITIONING with no end (docs/fidelity.md).
            frames.append((Command.PREPOSITION, {"flags": int(PrepositionFlag.STOP_ON_BLOCK), "width": width,
                                                 "speed": speed}))
        elif cmd == CmdFlag.GRIP:
            frames.append((Command.SET_FORCE_LIMIT, {"force": force}))
            frames.append((Command.GRIP_PART, {"width": width, "speed": speed}))
        elif cmd == CmdFlag.RELEASE:
            frames.append((Command.RELEASE_PART, {"width": width, "speed": speed}))
        self._emit(f"{cmd.name} width={width:.2f} mm speed={speed:.2f} mm/s force={force:g} N")
        if self._run(frames):
            self._shown = None   # accepted: the gripper state is the command's from here

    def _stop_ack(self, out: OutputImage) -> None:
        snap = self.gripper.snapshot()
        if snap.flags & SystemFlag.SF_FAST_STOP:
            if out.cmdflags & CmdFlag.FASTSTOP:
                self._emit("STOP/ACK ignored: reset FASTSTOP before acknowledging")
                self._set_status(Status.E_ACCESS_DENIED)
                return
            self._emit("STOP/ACK: acknowledge FAST STOP")
            if not self._run([(Command.ACK_FAST_STOP, {"key": "ack"})]):
                return
        else:
            self._emit("STOP/ACK: stop")
        self._stop_jog()
        if self._run([(Command.STOP, {})]):
            self._shown, self._failed = None, None
            if self.gripper.snapshot().gripper_state != GripperState.IDLE:
                # 002 §4.5: STOP/ACK sets the gripper state to IDLE (also from ERROR, HOLDING, NO_PART),
                # which 22h alone does not do when no motion was running.
                self.gripper.reset_gripper_state()
