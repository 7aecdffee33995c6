"""What the fieldbus controller sees of a bus: the :class:`BusAdapter` Protocol (device side).

One :class:`~pywsg.fieldbus.controller.FieldbusController` per gripper, fed by any number of bus
adapters (Modbus/TCP, PROFINET IO, PROFIBUS DP), as python-can keeps one bus interface with many
backends. An adapter

- passes the 8 output bytes a master wrote to ``controller.write_outputs(OutputImage.unpack(data))``
  and answers with ``controller.input_bytes()`` (12 bytes), fresh on every bus cycle;
- registers with ``controller.attach_bus(adapter)`` (and ``detach_bus`` when it stops), so the
  Fieldbus Monitor lists it;
- calls ``controller.fail_safe(adapter.name, reason)`` when its master is lost (watchdog expired,
  connection or application relationship aborted, Global_Control Clear): docs/fidelity.md says what
  the gripper does then.
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable


@runtime_checkable
class BusAdapter(Protocol):
    """One fieldbus serving a :class:`~pywsg.fieldbus.controller.FieldbusController`."""

    #: The bus's name as the Fieldbus Monitor shows it: "Modbus/TCP", "PROFINET IO", "PROFIBUS DP".
    name: str

    def bus_state(self) -> dict[str, str]:
        """Rows for the Fieldbus Monitor's Bus State box (003 §6), label → text, in display order,
        e.g. ``{"Station Address": "7", "Bitrate": "1.5 Mbit/s", "Interface state": "Data exchange"}``.
        Cheap: the web interface calls it on every live update."""
        ...

    async def close(self) -> None:
        """Stop serving; detach from the controller. The controller itself stays open (it may serve
        other buses): its owner closes it."""
        ...


__all__ = ["BusAdapter"]
