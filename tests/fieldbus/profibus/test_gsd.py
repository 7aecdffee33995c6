"""WEIS5555.gsd (002 §2.1.1, §3.3): parsed by pyprofibus's GSD parser, and the slave agrees with it."""

from __future__ import annotations

import pytest

from pywsg.fieldbus.profibus.gsd import facts, gsd_text, parse_facts
from pywsg.fieldbus.profibus.line import check_baudrate

from .pbmaster import gsd_path, pyprofibus


@pytest.fixture(scope="module")
def gsd() -> object:
    return pyprofibus.gsd.interp.GsdInterp.fromFile(gsd_path())


def test_pyprofibus_parses_it_with_the_manuals_facts(gsd: object) -> None:
    """002 §2.1.1: Ident 5555h, file WEIS5555.gsd; one module of 8 output and 12 input bytes."""
    assert gsd.getIdentNumber() == 0x5555  # type: ignore[attr-defined]
    assert gsd_path().endswith("WEIS5555.gsd")
    assert not gsd.isModular() and not gsd.isDPV1()  # type: ignore[attr-defined]
    cfg = b"".join(bytes(e.getDU()) for e in gsd.getCfgDataElements())  # type: ignore[attr-defined]
    assert cfg == b"\xa7\x9b"        # 0xA7: 8 bytes output, consistent; 0x9B: 12 bytes input, consistent
    assert gsd.getUserPrmData() == b""  # type: ignore[attr-defined]
    assert gsd.getField("Max_Diag_Data_Len") == 16  # type: ignore[attr-defined]   # 002 §3.3: 16 bytes
    for field in ("Freeze_Mode_supp", "Sync_Mode_supp", "Set_Slave_Add_supp"):
        assert gsd.getField(field) is True  # type: ignore[attr-defined]


def test_the_slave_reads_the_same_file(gsd: object) -> None:
    f = facts()
    assert f.ident_number == gsd.getIdentNumber()  # type: ignore[attr-defined]
    assert f.config == b"\xa7\x9b" and f.user_prm_len == 0 and f.max_diag_len == 16
    for rate in f.baud_rates:
        assert gsd.getMaxTSDR(rate) == f.max_tsdr[rate]  # type: ignore[attr-defined]
        check_baudrate(rate)
    with pytest.raises(ValueError, match=r"not one WEIS5555\.gsd declares"):
        check_baudrate(1_500_000)


def test_unit_diag_bits_name_each_error_flag_of_the_manual() -> None:
    """002 §3.3's error flags have a text at UnitDiagBit(8 + SYSSTATE bit) (docs/fidelity.md)."""
    from pywsg.fieldbus.profibus import DIAGNOSIS_FLAGS

    text = gsd_text()
    from pywsg.protocol import SystemFlag

    for flag in (f for f in SystemFlag if f.value and DIAGNOSIS_FLAGS & f):  # Python 3.10: no iter(flag)
        bit = int(flag).bit_length() - 1
        key = f"UnitDiagBit({8 + bit})"
        assert key in text and flag.name in text.split(key)[1].split("\n")[0]


def test_a_gsd_without_module_is_refused() -> None:
    with pytest.raises(ValueError, match="Module"):
        parse_facts("#Profibus_DP\nIdent_Number = 0x5555\n")
