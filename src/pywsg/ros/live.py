"""What the gripper's auto-update streams last said: opening, speed, force, gripper state, system flags.

Written by the driver's stream callbacks (one thread), read by the action, the services and the
diagnostics (others): each field is replaced whole, so a reader sees a value, old or new, never half
of one."""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass, field

from ..client import Sample
from ..protocol import Command, GripperState, SystemFlag


@dataclass
class Live:
    """The latest values (mm, mm/s, N) and when the width last came (``time.monotonic()``)."""

    width: float = 0.0
    speed: float = 0.0
    force: float = 0.0
    gripper_state: GripperState | int | None = None
    flags: SystemFlag | None = None
    width_time: float = 0.0
    widths: int = 0
    changed: threading.Condition = field(default_factory=threading.Condition)

    def take(self, sample: Sample) -> None:
        """Store one auto-update sample (43h–45h, 41h, 40h)."""
        cmd, value = sample.command, sample.value
        if cmd == Command.GET_OPENING_WIDTH:
            self.width = float(value)
            self.width_time = sample.time
            self.widths += 1
        elif cmd == Command.GET_SPEED:
            self.speed = float(value)
        elif cmd == Command.GET_FORCE:
            self.force = float(value)
        elif cmd == Command.GET_GRIPPER_STATE:
            self.gripper_state = value  # type: ignore[assignment]
        elif cmd == Command.GET_SYSTEM_STATE:
            self.flags = SystemFlag(int(value))
        with self.changed:
            self.changed.notify_all()

    def wait_width_after(self, t: float, timeout: float) -> bool:
        """Wait until a width sample newer than ``t`` (monotonic s) arrived; False after ``timeout`` s."""
        end = time.monotonic() + timeout
        with self.changed:
            while self.width_time <= t:
                left = end - time.monotonic()
                if left <= 0:
                    return False
                self.changed.wait(left)
        return True
