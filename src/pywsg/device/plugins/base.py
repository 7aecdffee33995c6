"""Base class of firmware plugins."""

from __future__ import annotations

from typing import TYPE_CHECKING, ClassVar

from ...protocol import Frame, Status

if TYPE_CHECKING:
    from ..gripper import VirtualGripper
    from ..session import Session


class FirmwarePlugin:
    """A script running on the virtual gripper.

    ``commands``: the command IDs it registers (not IDs of the manual). ``handle`` answers one
    request frame immediately; motion goes through the gripper's script motion API
    (:meth:`VirtualGripper.script_move`, :meth:`~VirtualGripper.script_speed`,
    :meth:`~VirtualGripper.script_stop`), readings through ``width``/``speed``/``force``/``system_flags``.
    ``on_if_changed`` is called when the fieldbus IF user flags change.
    """

    name: ClassVar[str] = "plugin"
    commands: ClassVar[tuple[int, ...]] = ()

    def start(self, gripper: VirtualGripper) -> None:
        """Called when the plugin is loaded."""

    def stop(self, gripper: VirtualGripper) -> None:
        """Called when the plugin is unloaded (stops any motion it started)."""
        gripper.script_stop()

    def handle(self, gripper: VirtualGripper, session: Session, command_id: int, payload: bytes,
               now: float) -> Frame:
        return Frame.reply(command_id, Status.E_CMD_UNKNOWN)

    def on_if_changed(self, gripper: VirtualGripper, value: int) -> None:
        """The fieldbus IF user flags (16 bits) changed."""


class MirrorPlugin(FirmwarePlugin):
    """Copies the fieldbus IF user flags to the OF user flags."""

    name = "if_of_mirror"

    def start(self, gripper: VirtualGripper) -> None:
        gripper.script_of = gripper.script_if

    def on_if_changed(self, gripper: VirtualGripper, value: int) -> None:
        gripper.script_of = value
