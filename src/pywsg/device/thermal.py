"""Temperature model: a first-order thermal mass, closed form between load changes.

T(t) = T_eq + (T_0 - T_eq) * exp(-(t - t_0) / tau), with T_eq = ambient + rise(load).
The load (holding force, motion) is piecewise constant, so the crossing time of a threshold
is solved exactly and a server can sleep until it.
All temperatures in °C, times in s. Thresholds and constants are assumed (the manuals give none).
"""

from __future__ import annotations

import math

AMBIENT_C = 25.0
IDLE_RISE_C = 5.0  # electronics alone
HOLD_RISE_C = 20.0  # at nominal force, scales with (F / F_nom)^2 (I^2 R losses)
MOVE_RISE_C = 3.0
TAU_S = 300.0
WARNING_C = 60.0
FAULT_C = 70.0
MIN_C = -40.0
MAX_C = 150.0
"""The temperature a world action may set (°C): an industrial sensor's range, far inside what 46h's
signed 0.1 °C field can carry (±3276.7 °C); docs/sim.md records the choice."""


class ThermalModel:
    __slots__ = ("ambient", "rise", "t0", "tau", "temp0")

    def __init__(self, t: float, ambient: float = AMBIENT_C, tau: float = TAU_S) -> None:
        self.ambient = ambient
        self.tau = tau
        self.rise = IDLE_RISE_C
        self.t0 = t
        self.temp0 = ambient + IDLE_RISE_C  # a gripper that has been powered for a while

    @property
    def equilibrium(self) -> float:
        return self.ambient + self.rise

    def temperature(self, t: float) -> float:
        dt = t - self.t0
        if dt <= 0:
            return self.temp0
        return self.equilibrium + (self.temp0 - self.equilibrium) * math.exp(-dt / self.tau)

    @staticmethod
    def rise_for(force_ratio: float, moving: bool) -> float:
        """Equilibrium rise above ambient for a force of ``force_ratio`` × nominal and motion."""
        return IDLE_RISE_C + HOLD_RISE_C * force_ratio * force_ratio + (MOVE_RISE_C if moving else 0.0)

    def set_load(self, t: float, rise: float) -> None:
        if rise == self.rise:
            return
        self.temp0 = self.temperature(t)
        self.t0 = t
        self.rise = rise

    def heat(self, t: float, delta: float) -> None:
        """Add ``delta`` °C at once (fault injection). Raises ValueError (naming ``delta_c``) when the
        result would leave :data:`MIN_C`..:data:`MAX_C`; the temperature is then unchanged."""
        now = self.temperature(t)
        new = now + delta
        if not (math.isfinite(new) and MIN_C <= new <= MAX_C):
            raise ValueError(f"delta_c: must keep the temperature within {MIN_C:g}..{MAX_C:g} °C "
                             f"(now {now:.1f} °C), not change it by {delta:+g}")
        self.temp0 = new
        self.t0 = t

    def crossing(self, threshold: float, after: float) -> float | None:
        """Time > ``after`` at which the temperature crosses ``threshold``, or None."""
        eq = self.equilibrium
        now_t = self.temperature(after)
        if (now_t - threshold) * (eq - threshold) >= 0:
            return None  # already past it, or never gets there
        # solve eq + (T0 - eq) e^{-(t - t0)/tau} = threshold from the state at ``after``
        ratio = (threshold - eq) / (now_t - eq)
        if ratio <= 0:
            return None
        return after - self.tau * math.log(ratio) + 1e-9
