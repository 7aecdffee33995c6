"""Flags and status codes print their names (issue 16 item 6): Python 3.11 prints IntFlag/IntEnum as numbers."""

from __future__ import annotations

from pywsg.protocol import GState, PrepositionFlag, Status, SystemFlag


def test_system_flags_print_their_names_lowest_bit_first() -> None:
    flags = SystemFlag.SF_CMD_FAILURE | SystemFlag.SF_REFERENCED   # Appendix B bits 18 and 0
    assert str(flags) == "SF_REFERENCED|SF_CMD_FAILURE"
    assert f"{flags}" == "SF_REFERENCED|SF_CMD_FAILURE"
    assert f"{flags:#x}" == "0x40001" and f"{flags:d}" == "262145"   # format specs still see the number
    assert int(flags) == 262145 and flags == 262145


def test_zero_and_unnamed_bits() -> None:
    assert str(SystemFlag(0)) == "NONE"
    assert str(PrepositionFlag(0)) == "ABSOLUTE"
    assert str(SystemFlag(1 << 30 | 1)) == "SF_REFERENCED|0x40000000"   # bit 30 is not in Appendix B
    assert str(GState.HOLDING) == "HOLDING"


def test_status_prints_its_name() -> None:
    assert str(Status.E_CMD_FAILED) == "E_CMD_FAILED"
    assert f"{Status.E_ACCESS_DENIED}" == "E_ACCESS_DENIED"
    assert int(Status.E_ACCESS_DENIED) == 16 and f"{Status.E_ACCESS_DENIED:d}" == "16"
