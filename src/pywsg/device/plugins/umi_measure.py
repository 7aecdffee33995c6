"""Emulation of the Stanford UMI driver's ``cmd_measure.lua`` script.

B0h measure only, B1h position PD control. Request: 1 unused byte, then float32 position (mm),
velocity (mm/s), kp (1/s), kd (1), travel force limit (N), blocked force limit (N). The script's
law ``speed = kp*(pos_cmd - pos) + kd*(vel_cmd - vel)`` is applied as a speed command; the force
limit is the blocked value while blocked, else the travel value. Reply: status, 1 byte (low byte
of the system state), 4 float32: position (mm), speed (mm/s), motor force (N), time (s).
"""

from __future__ import annotations

import struct

from ...protocol import Frame, Status
from ..session import Session
from .base import FirmwarePlugin, ScriptHost

REQUEST = struct.Struct("<B6f")
REPLY = struct.Struct("<B4f")


class UmiMeasurePlugin(FirmwarePlugin):
    name = "umi_measure"
    commands = (0xB0, 0xB1)

    def handle(self, gripper: ScriptHost, session: Session, command_id: int, payload: bytes,
               now: float) -> Frame:
        if command_id == 0xB1:
            if len(payload) < REQUEST.size:
                return Frame.reply(command_id, Status.E_CMD_FORMAT_ERROR)
            _, pos_cmd, vel_cmd, kp, kd, travel_force, blocked_force = REQUEST.unpack_from(payload)
            pos = gripper.width(now)
            vel = gripper.speed(now)
            act_vel = kp * (pos_cmd - pos) + kd * (vel_cmd - vel)
            force = blocked_force if gripper.blocked() else travel_force
            gripper.script_speed(act_vel, force=force, now=now)  # one clock reading per request
        state = int(gripper.system_flags(now)) & 0xFF
        return Frame.reply(command_id, Status.E_SUCCESS,
                           REPLY.pack(state, gripper.width(now), gripper.speed(now), gripper.force(now), now))
