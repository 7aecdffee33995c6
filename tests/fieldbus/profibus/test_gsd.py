"""WEIS5555.gsd (002 §2.1.1, §3.3): parsed by the GSD specification's rules and by pyprofibus's GSD
parser, and the slave agrees with it."""

from __future__ import annotations

from importlib import resources

import pytest

from pywsg.fieldbus.profibus import DIAGNOSIS_FLAGS
from pywsg.fieldbus.profibus.gsd import facts, gsd_text, parse_facts
from pywsg.fieldbus.profibus.line import check_baudrate
from pywsg.protocol import SystemFlag

from . import gsdspec
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
        check_baudrate(3_000_000)


def test_unit_diag_bits_name_each_error_flag_of_the_manual() -> None:
    """002 §3.3's error flags each have a text at Unit_Diag_Bit(8 + SYSSTATE bit) (docs/fidelity.md)."""
    words = {"SF_SOFT_LIMIT_MINUS": "Soft limit minus", "SF_SOFT_LIMIT_PLUS": "Soft limit plus",
             "SF_FAST_STOP": "Fast stop", "SF_TEMP_FAULT": "Temperature fault", "SF_POWER_FAULT": "Power fault",
             "SF_CURR_FAULT": "Engine current fault", "SF_FINGER_FAULT": "Finger fault",
             "SF_CMD_FAILURE": "Command failure", "SF_SCRIPT_FAILURE": "Script failure"}
    found, _ = gsdspec.check(gsd_text().encode("latin-1"))
    for flag in (f for f in SystemFlag if f.value and DIAGNOSIS_FLAGS & f):  # Python 3.10: no iter(flag)
        bit = int(flag).bit_length() - 1
        assert found[f"Unit_Diag_Bit({8 + bit})"] == f'"{words[str(flag.name)]}"'


def test_the_gsd_keeps_the_gsd_specification_rules() -> None:
    """Parsed by the specification's rules (tests/fieldbus/profibus/gsdspec.py), not only by
    pyprofibus's lenient parser: ASCII, lines of at most 80 characters, keywords as spelled there
    (Unit_Diag_Bit), names and texts of at most 32 characters, mandatory keywords."""
    raw = (resources.files("pywsg.fieldbus") / "descriptions" / "WEIS5555.gsd").read_bytes()
    found, problems = gsdspec.check(raw)
    assert problems == []
    assert found["Ident_Number"] == "0x5555" and found["Auto_Baud_supp"] == "1"


@pytest.mark.parametrize(("line", "problem"), [
    ('UnitDiagBit(20) = "Fast stop"', "unknown keyword 'UnitDiagBit'"),
    ('Unit_Diag_Bit(20) = "Engine current fault (SF_CURR_FAULT)"', "text of 36 characters (at most 32)"),
    ('Module = "WSG I/O: 8 bytes out, 12 bytes in" 0xA7,0x9B\nEndModule', "module name of 33 characters"),
    ("; 2017 \u00a72.1.1", "characters outside printable ASCII: '\u00a7'"),
    ("; " + "=" * 79, "81 characters (at most 80)"),
    ("Auto_Baud_supp = 2", "'2' is not a Boolean"),
])
def test_the_specification_check_catches_what_tools_refuse(line: str, problem: str) -> None:
    """Each fault the issue found in the old file (and two more) is caught by the check."""
    text = gsd_text().replace("Max_Diag_Data_Len   = 16", "Max_Diag_Data_Len   = 16\n" + line)
    if "Module" in line:
        text = text[:text.index("Module = ")] + line + "\n"
    _, problems = gsdspec.check(text.encode("latin-1"))
    assert any(problem in p for p in problems), problems


def test_a_gsd_without_module_is_refused() -> None:
    with pytest.raises(ValueError, match="Module"):
        parse_facts("#Profibus_DP\nIdent_Number = 0x5555\n")
