"""Base class of firmware plugins, and :class:`ScriptHost`: all a plugin may see of the gripper."""

from __future__ import annotations

from typing import ClassVar, Protocol

from ...protocol import Frame, Status, SystemFlag
from ..fingers import Finger
from ..session import Session


class ScriptHost(Protocol):
    """What an on-board script reaches: readings at a clock time, the script motion API, user flags.

    Units: width mm, speed mm/s (signed, of the opening width), force N, time s.
    """

    fingers: list[Finger]
    script_if: int
    script_of: int

    def width(self, now: float | None = None) -> float: ...

    def speed(self, now: float | None = None) -> float: ...

    def force(self, now: float | None = None) -> float: ...

    def moving(self, now: float | None = None) -> bool: ...

    def system_flags(self, now: float | None = None) -> SystemFlag: ...

    def blocked(self) -> bool: ...

    def script_move(self, width: float, speed: float, now: float | None = None) -> Status: ...

    def script_speed(self, velocity: float, force: float | None = None, now: float | None = None) -> Status: ...

    def script_stop(self, now: float | None = None) -> None: ...


class FirmwarePlugin:
    """A script running on the virtual gripper.

    ``commands``: the command IDs it registers (not IDs of the manual). ``handle`` answers one
    request frame immediately; motion goes through the gripper's script motion API
    (:meth:`ScriptHost.script_move`, :meth:`~ScriptHost.script_speed`,
    :meth:`~ScriptHost.script_stop`), readings through ``width``/``speed``/``force``/``system_flags``.
    ``on_if_changed`` is called when the fieldbus IF user flags change. Pass the request's ``now`` on to
    every call: one clock reading per request, so a reply describes the motion it just commanded.
    """

    name: ClassVar[str] = "plugin"
    commands: ClassVar[tuple[int, ...]] = ()

    def start(self, gripper: ScriptHost) -> None:
        """Called when the plugin is loaded."""

    def stop(self, gripper: ScriptHost) -> None:
        """Called when the plugin is unloaded (stops any motion it started)."""
        gripper.script_stop()

    def handle(self, gripper: ScriptHost, session: Session, command_id: int, payload: bytes,
               now: float) -> Frame:
        return Frame.reply(command_id, Status.E_CMD_UNKNOWN)

    def on_if_changed(self, gripper: ScriptHost, value: int) -> None:
        """The fieldbus IF user flags (16 bits) changed."""


class MirrorPlugin(FirmwarePlugin):
    """Copies the fieldbus IF user flags to the OF user flags."""

    name = "if_of_mirror"

    def start(self, gripper: ScriptHost) -> None:
        gripper.script_of = gripper.script_if

    def on_if_changed(self, gripper: ScriptHost, value: int) -> None:
        gripper.script_of = value
