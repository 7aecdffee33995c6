"""PROFIBUS DP-V0: the virtual WSG as a DP slave on a serial line (002 §2.1, §3.3; 003 §2, §4.2, §6).

- :mod:`.fdl` — FDL telegrams (SD1/SD2/SD3/SD4/SC, FCS), an incremental parser; sans-IO.
- :mod:`.dp` — :class:`DpSlave`, the Wait_Prm → Wait_Cfg → Data_Exch state machine; sans-IO.
- :mod:`.diagnosis` — the manual's 16-byte diagnosis message as plain functions.
- :mod:`.gsd` — the slave's facts from its packaged ``WEIS5555.gsd``.
- :mod:`.line` — :class:`ProfibusAdapter`, the slave on a pty or a serial port (asyncio).
- :mod:`.master` — the PLC side: an ``ImageExchange`` over pyprofibus (optional extra ``profibus``).

None of these modules imports pyprofibus except :mod:`.master`, and that only when used.
"""

from __future__ import annotations

from .diagnosis import (
    DEFAULT_STATION_ADDRESS,
    DIAGNOSIS_FLAGS,
    DIAGNOSIS_LENGTH,
    DIAGNOSIS_SIZE,
    IDENT_NUMBER,
    Diagnosis,
    DiagnosisMonitor,
    diagnosis_message,
    input_bytes,
    output_image,
    parse_diagnosis,
    raised_flags,
)

__all__ = [
    "DEFAULT_STATION_ADDRESS",
    "DIAGNOSIS_FLAGS",
    "DIAGNOSIS_LENGTH",
    "DIAGNOSIS_SIZE",
    "IDENT_NUMBER",
    "Diagnosis",
    "DiagnosisMonitor",
    "diagnosis_message",
    "input_bytes",
    "output_image",
    "parse_diagnosis",
    "raised_flags",
]
