"""The device's health: temperature warning and fault, power and motor-current faults (Appendix B).

:class:`Health` keeps the fault latches and the temperature state, logs their changes and says which
system flags they raise and whether they forbid motion. What a fault *does* to the fingers (FAST STOP,
aborting a motion) is the device core's business: this module knows nothing of motion.
Temperatures in °C, times in s.
"""

from __future__ import annotations

from ..protocol import SystemFlag
from .log import LogLevel, SystemLog
from .thermal import FAULT_C, WARNING_C, ThermalModel

_SF_TEMP_WARNING = int(SystemFlag.SF_TEMP_WARNING)
_SF_TEMP_FAULT = int(SystemFlag.SF_TEMP_FAULT)
_SF_POWER_FAULT = int(SystemFlag.SF_POWER_FAULT)
_SF_CURR_FAULT = int(SystemFlag.SF_CURR_FAULT)

NORMAL, WARNING, FAULT = 0, 1, 2  # temperature states


class Health:
    """Temperature state (from the thermal model) and the power / current fault latches."""

    def __init__(self, thermal: ThermalModel, log: SystemLog) -> None:
        self.thermal = thermal
        self.log = log
        self.temp_state = NORMAL
        self.power_fault = False
        self.current_fault = False

    def locked(self) -> bool:
        """A temperature, power or current fault forbids motion (and, for the latter two, the acknowledge)."""
        return self.temp_state >= FAULT or self.power_fault or self.current_fault

    def flag_bits(self) -> int:
        f = 0
        if self.temp_state >= WARNING:
            f |= _SF_TEMP_WARNING
        if self.temp_state >= FAULT:
            f |= _SF_TEMP_FAULT
        if self.power_fault:
            f |= _SF_POWER_FAULT
        if self.current_fault:
            f |= _SF_CURR_FAULT
        return f

    def next_crossing(self, now: float) -> float | None:
        """Clock time at which the temperature next crosses the warning or fault threshold."""
        first = None
        for threshold in (WARNING_C, FAULT_C):
            t = self.thermal.crossing(threshold, now)
            if t is not None and (first is None or t < first):
                first = t
        return first

    def update_temperature(self, now: float) -> bool:
        """Take the temperature state at ``now``; True if a temperature fault has just begun."""
        temp = self.thermal.temperature(now)
        state = FAULT if temp >= FAULT_C else WARNING if temp >= WARNING_C else NORMAL
        old = self.temp_state
        if state == old:
            return False
        self.temp_state = state
        if state == FAULT:
            self.log.add(now, LogLevel.ERROR, "temperature fault: motion disabled")
        elif state == WARNING and old == NORMAL:
            self.log.add(now, LogLevel.WARNING, "temperature warning")
        elif state < old:
            self.log.add(now, LogLevel.INFO, "temperature back below threshold")
        return state == FAULT
