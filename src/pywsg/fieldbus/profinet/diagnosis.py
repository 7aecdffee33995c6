"""Channel diagnosis of the WSG submodule from 002 §3.3's error flags, sans-IO (IEC 61158-6-10).

One source for both ways a controller learns of a fault: the Diagnosis alarms
(:mod:`pywsg.fieldbus.profinet.alarm`) and the diagnosis records it reads (800Ah/800Bh/800Ch for a
subslot, C00xh for a slot, E00xh for an AR, F00xh for the API, F80Ch for the device). Each listed flag that
is set is one ChannelDiagnosis item of the WSG submodule (slot 1, subslot 1): channel 8000h (the whole
submodule), ChannelErrorType from the standard where one fits, manufacturer types 0100h + flag bit otherwise
(the GSDML's ChannelDiagList names them).
"""

from __future__ import annotations

import struct

from ...protocol import SystemFlag

F = SystemFlag
#: The listed error flags (002 §3.3) and their ChannelErrorType.
ERROR_TYPES: dict[SystemFlag, int] = {
    F.SF_SOFT_LIMIT_MINUS: 0x0008,    # lower limit value exceeded
    F.SF_SOFT_LIMIT_PLUS: 0x0007,     # upper limit value exceeded
    F.SF_FAST_STOP: 0x010C,
    F.SF_TEMP_FAULT: 0x0005,          # overtemperature
    F.SF_POWER_FAULT: 0x010F,
    F.SF_CURR_FAULT: 0x0004,          # overload
    F.SF_FINGER_FAULT: 0x0111,
    F.SF_CMD_FAILURE: 0x0112,
    F.SF_SCRIPT_FAILURE: 0x0114,
}
DIAGNOSIS_FLAGS = 0
for _f in ERROR_TYPES:
    DIAGNOSIS_FLAGS |= int(_f)

USI_CHANNEL_DIAGNOSIS = 0x8000
WHOLE_SUBMODULE = 0x8000
# ChannelProperties.Specifier (bits 11-12)
APPEARS, DISAPPEARS, DISAPPEARS_OTHERS_REMAIN = 1, 2, 3
DIAGNOSIS_DATA = 0x0010
WSG_SLOT, WSG_SUBSLOT = 1, 1

#: Record indices: channel coding (xx0Ah), all codings (xx0Bh), with maintenance and qualified (xx0Ch),
#: by the part of the device they cover.
SUBSLOT_RECORDS = (0x800A, 0x800B, 0x800C)
SLOT_RECORDS = (0xC00A, 0xC00B, 0xC00C)
AR_RECORDS = (0xE00A, 0xE00B, 0xE00C)
API_RECORDS = (0xF00A, 0xF00B, 0xF00C)
DEVICE_RECORDS = (0xF80C,)
RECORDS = SUBSLOT_RECORDS + SLOT_RECORDS + AR_RECORDS + API_RECORDS + DEVICE_RECORDS


def error_types(flags: int) -> list[int]:
    """ChannelErrorType of each listed flag set in ``flags`` (SYSSTATE), in the table's order."""
    return [t for f, t in ERROR_TYPES.items() if flags & int(f)]


def channel_item(error_type: int, specifier: int) -> bytes:
    """One ChannelDiagnosis item: ChannelNumber, ChannelProperties (Specifier), ChannelErrorType."""
    return struct.pack("!HHH", WHOLE_SUBMODULE, specifier << 11, error_type)


def diagnosis_data(api: int, flags: int) -> bytes:
    """The DiagnosisData block (0010h, version 1.1) of the WSG submodule with its active channel
    diagnosis, or b"" when no listed flag is set (an empty record: nothing to report)."""
    types = error_types(flags)
    if not types:
        return b""
    body = (struct.pack("!IHHHHH", api, WSG_SLOT, WSG_SUBSLOT, WHOLE_SUBMODULE, APPEARS << 11, USI_CHANNEL_DIAGNOSIS)
            + b"".join(channel_item(t, APPEARS) for t in types))
    return struct.pack("!HHBB", DIAGNOSIS_DATA, len(body) + 2, 1, 1) + body


def covers_wsg(index: int, slot: int, subslot: int) -> bool:
    """Whether record ``index`` read at slot/subslot includes the WSG submodule."""
    if index in SUBSLOT_RECORDS:
        return (slot, subslot) == (WSG_SLOT, WSG_SUBSLOT)
    if index in SLOT_RECORDS:
        return slot == WSG_SLOT
    return index in AR_RECORDS + API_RECORDS + DEVICE_RECORDS
