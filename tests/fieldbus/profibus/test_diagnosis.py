"""PROFIBUS diagnosis message (002 §3.3, 003 §4.2) and image bytes, as plain functions."""

from __future__ import annotations

import pytest

from pywsg.fieldbus.image import CmdFlag, InputImage
from pywsg.fieldbus.profibus import (
    DIAGNOSIS_FLAGS,
    DiagnosisMonitor,
    diagnosis_message,
    input_bytes,
    output_image,
    parse_diagnosis,
    raised_flags,
)
from pywsg.protocol import GState, SystemFlag


def test_message_layout() -> None:
    flags = SystemFlag.SF_REFERENCED | SystemFlag.SF_FAST_STOP
    msg = diagnosis_message(flags, master_address=2)
    assert len(msg) == 16
    assert msg[0] & 0x08                       # station status 1: extended diagnosis follows
    assert msg[3] == 2                         # master address
    assert msg[4:6] == b"\x55\x55"             # slave ident 5555h
    assert msg[6] == 0x0A                      # length 10 bytes
    # "Same coding as SYSSTATE" (002 §3.3): REFERENCED byte 7 bit 0, FAST_STOP (bit 12) byte 8 bit 4
    assert msg[7:11] == bytes([0x01, 0x10, 0x00, 0x00])
    assert msg[7:11] == InputImage(sysstate=flags).pack()[2:6]
    assert msg[11:] == bytes(5)                # reserved
    parsed = parse_diagnosis(msg)
    assert parsed.sysstate == flags and parsed.ident == 0x5555 and parsed.length == 10


def test_parse_rejects_foreign_messages() -> None:
    msg = bytearray(diagnosis_message(0))
    msg[4] = 0x12
    with pytest.raises(ValueError, match="ident"):
        parse_diagnosis(bytes(msg))
    with pytest.raises(ValueError):
        parse_diagnosis(b"\x00" * 15)


def test_listed_flags_are_the_manuals() -> None:
    assert DIAGNOSIS_FLAGS == (SystemFlag.SF_SOFT_LIMIT_MINUS | SystemFlag.SF_SOFT_LIMIT_PLUS
                               | SystemFlag.SF_FAST_STOP | SystemFlag.SF_TEMP_FAULT | SystemFlag.SF_POWER_FAULT
                               | SystemFlag.SF_CURR_FAULT | SystemFlag.SF_FINGER_FAULT
                               | SystemFlag.SF_CMD_FAILURE | SystemFlag.SF_SCRIPT_FAILURE)


@pytest.mark.parametrize("flag", [f for f in SystemFlag if f.value and DIAGNOSIS_FLAGS & f])  # 3.10: no iter(flag)
def test_each_listed_flag_rising_produces_a_message(flag: SystemFlag) -> None:
    mon = DiagnosisMonitor()
    base = SystemFlag.SF_REFERENCED
    assert mon.update(base) is None
    msg = mon.update(base | flag)
    assert msg is not None and parse_diagnosis(msg).sysstate == base | flag
    assert mon.update(base | flag) is None     # held: no new message
    assert mon.update(base) is None            # falling: none
    assert mon.update(base | flag) is not None  # rising again


def test_other_flags_produce_none() -> None:
    mon = DiagnosisMonitor()
    for flag in (SystemFlag.SF_MOVING, SystemFlag.SF_TEMP_WARNING, SystemFlag.SF_AXIS_STOPPED,
                 SystemFlag.SF_SCRIPT_RUNNING, SystemFlag.SF_BLOCKED_MINUS):
        assert mon.update(flag) is None
    assert raised_flags(SystemFlag.SF_FAST_STOP, SystemFlag.SF_FAST_STOP | SystemFlag.SF_MOVING) == 0


def test_profibus_image_bytes_are_the_same_layout() -> None:
    out = output_image(bytes([0x01, 0x20, 0x0B, 0xB8, 0x9C, 0x40, 0x1F, 0x40]))
    assert out.cmdflags == CmdFlag.MOVE and out.if_flags == 0x20
    assert (out.width, out.speed, out.force_limit) == (3000, 40000, 8000)   # the SCL demo's PreposWidth...
    assert input_bytes(InputImage(GState.IDLE))[0] == 1
