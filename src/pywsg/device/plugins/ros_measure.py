"""Emulation of the public WSG ROS driver's ``cmd_measure.lua`` script.

B0h measure only, B1h position control, B2h speed control. Request: 1 unused byte, float32
width (mm), float32 speed (mm/s). Reply: status, 1 byte (low byte of the system state),
5 float32: width (mm), speed (mm/s), motor force (N), finger 0 force, finger 1 force (N; NaN
unless WSG-FMF fingers are fitted, counted from finger 0 as the script does).
"""

from __future__ import annotations

import math
import struct

from ...protocol import FingerType, Frame, Status
from ..session import Session
from .base import FirmwarePlugin, ScriptHost

REQUEST = struct.Struct("<Bff")
REPLY = struct.Struct("<B5f")


SPEED_STOP_WIDTH = 50.0  # mm: the script's fixed threshold ("pos <= 50" / "pos >= 50")


class RosMeasurePlugin(FirmwarePlugin):
    """``cmd_measure.lua``: per request, measure (busy, blocked, position), act, then reply."""

    name = "ros_measure"
    commands = (0xB0, 0xB1, 0xB2)

    def __init__(self) -> None:
        self.speed_mode = False  # the script's is_speed
        self.speed = 5.0  # the script's def_speed (mm/s), 5 at start

    def handle(self, gripper: ScriptHost, session: Session, command_id: int, payload: bytes,
               now: float) -> Frame:
        if command_id in (0xB1, 0xB2) and len(payload) < REQUEST.size:
            return Frame.reply(command_id, Status.E_CMD_FORMAT_ERROR)
        # ==== Measurements (1): before the command, as the script reads them
        blocked = gripper.blocked()
        pos = gripper.width(now)
        if command_id == 0xB1:
            _, width, speed = REQUEST.unpack_from(payload)
            # "if busy then mc.stop(); end; mc.move(...)" in one tick: the move takes over from the current
            # speed (a drive does not stop in zero time); B1h leaves is_speed as it is
            gripper.script_move(width, abs(speed), now)
        elif command_id == 0xB2:
            _, _, speed = REQUEST.unpack_from(payload)
            self.speed_mode = True
            self.speed = speed
            gripper.script_speed(speed, now=now)
        # ==== Actions: stop a speed motion blocked closing at <= 50 mm or opening at >= 50 mm
        if blocked and self.speed_mode and (
                (pos <= SPEED_STOP_WIDTH and self.speed < 0) or (pos >= SPEED_STOP_WIDTH and self.speed > 0)):
            gripper.script_stop(now)
            self.speed_mode = False
        return Frame.reply(command_id, Status.E_SUCCESS, measure(gripper, now))


def measure(gripper: ScriptHost, now: float) -> bytes:
    state = int(gripper.system_flags(now)) & 0xFF  # "Only the lowest byte of state is sent!"
    forces = [math.nan, math.nan]
    force = gripper.force(now)
    for i, f in enumerate(gripper.fingers):
        if f.type != FingerType.WSG_FMF:
            break
        forces[i] = f.fmf_force(force)
    return REPLY.pack(state, gripper.width(now), gripper.speed(now), force, forces[0], forces[1])
