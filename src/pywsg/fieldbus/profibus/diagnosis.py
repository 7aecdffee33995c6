"""PROFIBUS / PROFINET side of the fieldbus interface, as plain functions (002 §2.1, §2.2, §3.3).

There is no PROFIBUS or PROFINET hardware here: these functions produce exactly the bytes a WSG
would exchange, so a bus stack (or a test) can carry them. PROFIBUS and PROFINET use the same
8-byte output / 12-byte input image as Modbus/TCP (:mod:`pywsg.fieldbus.image`).

Diagnosis message (16 bytes), sent when one of :data:`DIAGNOSIS_FLAGS` rises from 0 to 1:

=======  ==========================================================================
bytes    content
=======  ==========================================================================
0..3     standard diagnostic data: station status 1..3, master address (PROFIBUS DP)
4..5     slave ident number 5555h
6        length of the device-related diagnosis: 0Ah (10 bytes, this byte included)
7..10    SYSSTATE, same coding as input bytes 2..5: flag bit n in byte 7 + n // 8, bit n % 8
11..15   reserved, 0
=======  ==========================================================================
"""

from __future__ import annotations

import struct
from dataclasses import dataclass, field

from ...protocol import SystemFlag
from ..image import INPUT_SIZE, OUTPUT_SIZE, InputImage, OutputImage, sysstate_bytes, sysstate_from_bytes

IDENT_NUMBER = 0x5555
DIAGNOSIS_LENGTH = 0x0A
DIAGNOSIS_SIZE = 16
DEFAULT_STATION_ADDRESS = 7   # 002 §2.1.2: predefined PROFIBUS station address

#: Error-related flags whose 0→1 edge makes the gripper send a diagnosis message (002 §3.3).
DIAGNOSIS_FLAGS = (
    SystemFlag.SF_SOFT_LIMIT_MINUS | SystemFlag.SF_SOFT_LIMIT_PLUS | SystemFlag.SF_FAST_STOP
    | SystemFlag.SF_TEMP_FAULT | SystemFlag.SF_POWER_FAULT | SystemFlag.SF_CURR_FAULT
    | SystemFlag.SF_FINGER_FAULT | SystemFlag.SF_CMD_FAILURE | SystemFlag.SF_SCRIPT_FAILURE
)

# Station status 1 bit 3 (Diag.Ext_Diag): device-related diagnosis follows. Station status 2 bit 2
# is fixed to 1 by the PROFIBUS DP standard.
_STATUS1_EXT_DIAG = 0x08
_STATUS2_FIXED = 0x04
# Slave ident big-endian (PROFIBUS), SYSSTATE in the image's bit order ("same coding as SYSSTATE", 002 §3.3).
_DIAG = struct.Struct(">BBBBHB4s5x")


def diagnosis_message(sysstate: SystemFlag | int, master_address: int = 2) -> bytes:
    """The 16-byte diagnosis message carrying ``sysstate``.

    ``master_address`` is the address of the DP master that parameterised the slave (the manual's
    demo PLC uses 2).
    """
    if not 0 <= master_address <= 0xFF:
        raise ValueError("master address is one byte")
    return _DIAG.pack(_STATUS1_EXT_DIAG, _STATUS2_FIXED, 0, master_address, IDENT_NUMBER, DIAGNOSIS_LENGTH,
                      sysstate_bytes(sysstate))


@dataclass(frozen=True)
class Diagnosis:
    """A parsed diagnosis message."""

    station_status: tuple[int, int, int]
    master_address: int
    ident: int
    length: int
    sysstate: SystemFlag


def parse_diagnosis(data: bytes) -> Diagnosis:
    """Parse a 16-byte diagnosis message; raises ValueError on a wrong size, ident or length."""
    if len(data) != DIAGNOSIS_SIZE:
        raise ValueError(f"diagnosis message is {DIAGNOSIS_SIZE} bytes, got {len(data)}")
    s1, s2, s3, master, ident, length, sysstate = _DIAG.unpack(data)
    if ident != IDENT_NUMBER or length != DIAGNOSIS_LENGTH:
        raise ValueError(f"not a WSG diagnosis message (ident {ident:04X}h, length {length:02X}h)")
    return Diagnosis((s1, s2, s3), master, ident, length, sysstate_from_bytes(sysstate))


def raised_flags(previous: SystemFlag | int, current: SystemFlag | int) -> SystemFlag:
    """The diagnosis flags that changed from 0 to 1 between two SYSSTATE values."""
    return SystemFlag(int(current) & ~int(previous) & int(DIAGNOSIS_FLAGS))


@dataclass
class DiagnosisMonitor:
    """Feed SYSSTATE every bus cycle; get a diagnosis message when a listed flag rises."""

    master_address: int = 2
    previous: SystemFlag = field(default=SystemFlag.NONE)

    def update(self, sysstate: SystemFlag | int) -> bytes | None:
        """The message to send for this cycle, or None."""
        rose = raised_flags(self.previous, sysstate)
        self.previous = SystemFlag(int(sysstate))
        return diagnosis_message(sysstate, self.master_address) if rose else None


def output_image(data: bytes) -> OutputImage:
    """The 8 output bytes a PROFIBUS master / PROFINET controller sends, parsed."""
    if len(data) != OUTPUT_SIZE:
        raise ValueError(f"output image is {OUTPUT_SIZE} bytes")
    return OutputImage.unpack(data)


def input_bytes(image: InputImage) -> bytes:
    """The 12 input bytes the slave returns each bus cycle."""
    data = image.pack()
    assert len(data) == INPUT_SIZE
    return data
