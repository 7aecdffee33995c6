"""The finger interface (3.6): two sensor ports, each with a generic, WSG-FMF or WSG-DSA finger.

Data frames of Get Finger Data (63h/73h), little endian — the real layouts are in the fingers'
own manuals, which are not public; these are the virtual gripper's, documented in docs/device.md:

- generic: no data (SIZE 0; 63h answers E_NOT_AVAILABLE).
- WSG-FMF (force measurement finger): 4 bytes, float32 force on this finger in N (tared).
- WSG-DSA (tactile sensor array): 168 bytes, 14 rows × 6 columns of uint16 cell values
  (0..4095), row-major from the finger tip, proportional to the local contact pressure.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

from ..protocol import FingerFlag, FingerType

FMF_FRAME = struct.Struct("<f")
DSA_ROWS = 14
DSA_COLS = 6
DSA_FRAME = struct.Struct(f"<{DSA_ROWS * DSA_COLS}H")
DSA_MAX = 4095
FMF_ZERO_DRIFT_N = 0.2  # assumed zero offset of an untared force sensor
POWER_UP_S = 0.5  # manual: E_SUCCESS "after approx. 500 ms"

_TYPES = {"generic": FingerType.GENERIC, "fmf": FingerType.WSG_FMF, "dsa": FingerType.WSG_DSA}


@dataclass(slots=True)
class Finger:
    """One sensor port's finger."""

    type: FingerType = FingerType.GENERIC
    powered: bool = True  # "All fingers are powered up on system startup by default"
    powering_until: float | None = None  # power-up in progress until this time
    fault: bool = False  # over-current (POWER_FAULT)
    comm_fault: bool = False
    tare_offset: float = 0.0

    @classmethod
    def of(cls, name: str) -> Finger:
        return cls(type=_TYPES[name])

    @property
    def frame_size(self) -> int:
        if self.type == FingerType.WSG_FMF:
            return FMF_FRAME.size
        if self.type == FingerType.WSG_DSA:
            return DSA_FRAME.size
        return 0

    def flags(self) -> FingerFlag:
        f = FingerFlag.NONE
        if self.powered:
            f |= FingerFlag.POWER_ON
        if self.type != FingerType.GENERIC and self.powered and not self.comm_fault:
            f |= FingerFlag.CONFIG_AVAIL | FingerFlag.COMM_OPEN  # an unplugged finger has neither
        if self.fault:
            f |= FingerFlag.POWER_FAULT
        if self.comm_fault:
            f |= FingerFlag.COMM_FAULT
        return f

    def fmf_force(self, force: float) -> float:
        """The FMF reading in N for a grip force ``force`` (each jaw feels the whole grip force)."""
        return force + FMF_ZERO_DRIFT_N - self.tare_offset

    def data(self, force: float, contact: bool) -> bytes:
        if self.type == FingerType.WSG_FMF:
            return FMF_FRAME.pack(self.fmf_force(force))
        if self.type == FingerType.WSG_DSA:
            return DSA_FRAME.pack(*dsa_cells(force, contact))
        return b""


def dsa_cells(force: float, contact: bool) -> list[int]:
    """Tactile image: a contact patch over the middle rows/columns, pressure ∝ force."""
    cells = [0] * (DSA_ROWS * DSA_COLS)
    if not contact or force <= 0:
        return cells
    patch = [(r, c) for r in range(4, 10) for c in range(1, 5)]
    value = min(DSA_MAX, int(force * 20))  # 20 counts per N, assumed
    for r, c in patch:
        cells[r * DSA_COLS + c] = value
    return cells
