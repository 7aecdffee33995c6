"""Jog mode (002 §4.7 JOG+ and JOG-, 003 §5.7): levels, not edges.

JOG+ / JOG- are levels: 10 → positive, 01 → negative, 11 → stop, 00 after jogging → stop. SPEED 0
means the minimum speed; FORCELIMIT 0 keeps the current force limit. A new SPEED or FORCELIMIT while
jogging is taken at once (a hand wheel). Jog is refused while STOP/ACK or FASTSTOP is held, in FAST
STOP, and from the gripper states :data:`~pywsg.fieldbus.status_image.STARTS_FROM` does not list.
"""

from __future__ import annotations

from ..protocol import Status, SystemFlag
from .image import JOG, CmdFlag, OutputImage
from .status_image import StatusImage


class Jog(StatusImage):
    """The jog levels of the output image, driven through ``gripper.jog()``."""

    def _update_jog(self, out: OutputImage, blocked: bool) -> None:
        bits = out.cmdflags & JOG
        direction = 1 if bits == CmdFlag.JOG_PLUS else -1 if bits == CmdFlag.JOG_MINUS else 0
        if direction == self._jog_dir:
            if direction and (out.speed, out.force_limit) != (self._jog_params):
                self._start_jog(direction, out)   # hand wheel: new speed / force while jogging
            return
        if direction == 0:
            self._emit("JOG stop" if bits else "JOG mode left")
            self._stop_jog()
            self._set_status(Status.E_SUCCESS)
            return
        if blocked:
            self._stop_jog()
            self._set_status(Status.E_ACCESS_DENIED)
            return
        snap = self.gripper.snapshot()
        if snap.flags & SystemFlag.SF_FAST_STOP:
            self._stop_jog()
            self._set_status(Status.E_ACCESS_DENIED)
            return
        if not self._jog_dir and self._refused(JOG):
            return
        speed, force = out.speed / 100, out.force_limit / self.force_scale
        if speed > self.limits.max_speed or force > self._max_force() or force < 0:
            self._raise_fast_stop(f"JOG: SPEED {speed:g} mm/s / FORCELIMIT {force:g} N beyond limits",
                                  Status.E_RANGE_ERROR)
            return
        self._start_jog(direction, out)

    _jog_params: tuple[int, int] = (0, 0)

    def _start_jog(self, direction: int, out: OutputImage) -> None:
        speed = max(out.speed / 100, self.limits.min_speed)     # SPEED 0: minimum speed (002 §4.7)
        force = out.force_limit / self.force_scale if out.force_limit else self._current_force_limit()
        speed = min(speed, self.limits.max_speed)
        force = min(force, self._max_force())
        self._emit(f"JOG{'+' if direction > 0 else '-'} speed={speed:.2f} mm/s force={force:g} N")
        self._pending = None
        if direction == self._jog_dir:
            self.gripper.jog(0, 0.0, 0.0)   # the device keeps a running jog's speed: restart it
        status = int(self.gripper.jog(direction, speed, force))
        if status != Status.E_SUCCESS:
            self._emit(f"JOG refused: {Status.describe(status)}")
            self._set_status(status)
            self._jog_dir = 0
            return
        self._jog_dir = direction
        self._jog_done = False
        self._shown = None
        self._jog_params = (out.speed, out.force_limit)
        self._set_status(Status.E_CMD_PENDING)
