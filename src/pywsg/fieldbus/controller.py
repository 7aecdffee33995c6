"""The fieldbus controller: turns output-image updates into gripper commands (002 §3.1, §4).

Sans-IO. It drives the virtual gripper through its own device session ("fieldbus") with ordinary
request frames (20h Homing, 21h Pre-position, 22h Stop, 23h FAST STOP, 24h Ack, 25h Grip, 26h Release,
32h Set Force Limit), so every rule of the binary protocol holds for the bus too; final replies come
back through the session's ``deliver`` callback. Jog mode uses ``gripper.jog()``.

The rules live beside the manual's sections, each a base class of :class:`FieldbusController`:

- :mod:`~pywsg.fieldbus.commands` — the output image's commands, fired by CMDFLAGS edges (002 §3.1,
  §4.1–4.6: MOVE, GRIP, RELEASE, HOMING, STOP/ACK, FAST STOP; parameter checks; IF flags);
- :mod:`~pywsg.fieldbus.jog` — JOG+ / JOG- levels (002 §4.7);
- :mod:`~pywsg.fieldbus.status_image` — the input image the PLC reads: GSTATE on top of the device's
  state, SYSSTATE, STATUS CODE, OF (002 §3.2), and which gripper state allows which command;
- :mod:`~pywsg.fieldbus.device_session` — the controller's device session: requests, final replies,
  STATUS CODE, the system limits, raising FAST STOP, the event log.

The decisions where the manuals are silent are in docs/fieldbus.md and docs/fidelity.md.

One controller, many buses: every bus adapter (:class:`~pywsg.fieldbus.bus.BusAdapter`) of the
gripper feeds this one controller and registers with :meth:`FieldbusController.attach_bus`; a bus
whose master is lost calls :meth:`FieldbusController.fail_safe` (FAST STOP, outputs to zero: the
decision and its reasons are in docs/fidelity.md, "Fieldbus master lost").
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from ..protocol import GripperState, Status
from .commands import OutputCommands
from .device_session import Event, FieldbusDevice, Limits
from .image import CmdFlag, OutputImage, force_scale
from .status_image import RUNNING_STATES, STARTS_FROM, SnapshotLike

if TYPE_CHECKING:
    from .bus import BusAdapter

__all__ = ["RUNNING_STATES", "STARTS_FROM", "Event", "FieldbusController", "FieldbusDevice", "Limits",
           "SnapshotLike"]

log = logging.getLogger(__name__)

GS = GripperState


def _model_name(gripper: Any) -> str:
    profile = getattr(gripper, "profile", None)
    key = getattr(profile, "key", None)
    if isinstance(key, str):
        return key
    for attr in ("model_name", "model"):
        value = getattr(gripper, attr, None)
        if isinstance(value, str):
            return value
        name = getattr(value, "name", None)
        if isinstance(name, str):
            return name
    return "wsg50"


class FieldbusController(OutputCommands):
    """Fieldbus interface of one virtual gripper.

    ``write_outputs(image)`` applies a new output image (as a bus cycle would); ``input_image()``
    computes the input image fresh from the gripper's state; ``output_image`` is the last image
    written. ``model`` ("wsg50", "wsg70", ...) selects the force unit; by default it is taken from
    the gripper.
    """

    def __init__(self, gripper: FieldbusDevice, model: str | None = None) -> None:
        self.gripper = gripper
        self.model = (model or _model_name(gripper)).lower()
        self.force_scale = force_scale(self.model)
        self.output_image = OutputImage()
        self.status: int = int(Status.E_SUCCESS)
        self.events: list[Event] = []
        self._pending: int | None = None   # command ID whose final reply sets STATUS
        self._jog_dir = 0
        self._jog_done = False
        # The fieldbus gripper state shown instead of the device's (ERROR after a failed motion, IDLE
        # after FAST STOP) until the next accepted command; _failed is a final error not yet resolved.
        self._shown: GripperState | None = None
        self._failed: tuple[CmdFlag, int] | None = None
        self._listeners: list[Callable[[Event], None]] = []
        self._buses: list[BusAdapter] = []
        self.session = gripper.open_session("fieldbus", peer="fieldbus", deliver=self._deliver)
        self.limits = self._read_limits()

    # --- public --------------------------------------------------------------------------------


    # --- buses -----------------------------------------------------------------------------------
    @property
    def buses(self) -> tuple[BusAdapter, ...]:
        """The bus adapters feeding this controller, in the order they attached."""
        return tuple(self._buses)

    def attach_bus(self, adapter: BusAdapter) -> None:
        """Register a bus adapter (listed by :attr:`buses`, shown by the Fieldbus Monitor)."""
        if adapter not in self._buses:
            self._buses.append(adapter)

    def detach_bus(self, adapter: BusAdapter) -> None:
        """Forget a bus adapter that stopped serving (no error if it was not attached)."""
        if adapter in self._buses:
            self._buses.remove(adapter)

    def fail_safe(self, bus: str, reason: str) -> None:
        """A bus lost its master: FAST STOP, and the output image falls back to all zeros.

        Called by a bus adapter when its master is gone without saying goodbye (PROFINET AR watchdog
        or abort, PROFIBUS watchdog or Global_Control Clear). As an unannounced TCP close (000
        §1.4.2: "lost connections must be considered as severe errors"), it raises FAST STOP (STATUS =
        E_CMD_ABORTED; a running motion or jog stops; the master acknowledges with STOP/ACK when it
        is back). The outputs the lost master left behind are dropped, as PROFIBUS DP slaves drop
        theirs to the fail-safe value 0: the IF flags clear, no jog level stays raised, and the
        returning master's first image is read against zeros. docs/fidelity.md, "Fieldbus master lost".
        """
        log.warning("fieldbus %s: master lost (%s): FAST STOP", bus, reason)
        self._stop_jog()
        self._raise_fast_stop(f"{bus} master lost ({reason})", Status.E_CMD_ABORTED)
        if self.output_image.if_flags:
            self._set_script_if(0)
        self.output_image = OutputImage()

    def close(self) -> None:
        """Close the controller's device session (stops a running jog)."""
        if self._jog_dir:
            self.gripper.jog(0, 0.0, 0.0)
            self._jog_dir = 0
        self.gripper.close_session(self.session)


    # --- commands ------------------------------------------------------------------------------


    # --- helpers -------------------------------------------------------------------------------


