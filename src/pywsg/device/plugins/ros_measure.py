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


class RosMeasurePlugin(FirmwarePlugin):
    name = "ros_measure"
    commands = (0xB0, 0xB1, 0xB2)

    def __init__(self) -> None:
        self.speed_mode = False
        self.speed = 0.0

    def handle(self, gripper: ScriptHost, session: Session, command_id: int, payload: bytes,
               now: float) -> Frame:
        if command_id in (0xB1, 0xB2):
            if len(payload) < REQUEST.size:
                return Frame.reply(command_id, Status.E_CMD_FORMAT_ERROR)
            _, width, speed = REQUEST.unpack_from(payload)
            if command_id == 0xB1:
                self.speed_mode = False
                if gripper.moving(now):
                    gripper.script_stop()
                gripper.script_move(width, abs(speed))
            else:
                self.speed_mode = True
                self.speed = speed
                gripper.script_speed(speed)
        # the script stops a speed motion that ran into a block
        if self.speed_mode and gripper.blocked():
            gripper.script_stop()
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
