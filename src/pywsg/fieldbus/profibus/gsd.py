"""The slave's own facts read from its packaged GSD file ``WEIS5555.gsd`` (002 §2.1.1).

One source of truth: the slave checks Chk_Cfg against the GSD's module, accepts only the baud rates the
GSD declares, and reports the MaxTsdr it declares. A tiny reader of the keywords the slave needs (a
full GSD parser is the master's business: the tests parse the same file with pyprofibus's).
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from functools import cache
from importlib import resources

GSD_NAME = "WEIS5555.gsd"

_BAUD_KEYS = {
    9600: "9.6", 19200: "19.2", 45450: "45.45", 93750: "93.75", 187500: "187.5", 500000: "500",
    1500000: "1.5M", 3000000: "3M", 6000000: "6M", 12000000: "12M",
}
_LINE = re.compile(r'^\s*([A-Za-z0-9_.]+(?:\(\d+\))?)\s*=\s*(.*?)\s*$')
_TEXTS = ("Vendor_Name", "Model_Name", "Implementation_Type", "Hardware_Release", "Software_Release")
_MODULE = re.compile(r'^\s*Module\s*=\s*"([^"]*)"\s*(.*?)\s*$')


@dataclass(frozen=True)
class GsdFacts:
    """What the slave takes from its GSD."""

    ident_number: int
    config: bytes
    """Chk_Cfg data of the (only) module: identifier bytes as the GSD lists them."""
    module_name: str
    baud_rates: tuple[int, ...]
    """Supported baud rates in bit/s."""
    max_tsdr: dict[int, int]
    """Baud rate → MaxTsdr in bit times."""
    max_diag_len: int
    user_prm_len: int
    vendor_name: str = ""
    model_name: str = ""
    implementation_type: str = ""
    hardware_release: str = ""
    software_release: str = ""

    def max_tsdr_s(self, baudrate: int) -> float:
        """MaxTsdr at ``baudrate`` in seconds."""
        return self.max_tsdr[baudrate] / baudrate


def gsd_text() -> str:
    """The packaged GSD file's text (ISO 8859-1, as GSD files are)."""
    ref = resources.files("pywsg.fieldbus") / "descriptions" / GSD_NAME
    return ref.read_bytes().decode("latin-1")


def baud_key(baudrate: int) -> str:
    """The GSD's name for a baud rate: 45450 → ``45.45`` (as in ``45.45_supp``, ``MaxTsdr_45.45``)."""
    return _BAUD_KEYS[baudrate]


def parse_facts(text: str) -> GsdFacts:
    """Read the facts from GSD ``text``; ValueError when one is missing."""
    fields: dict[str, str] = {}
    module: tuple[str, bytes] | None = None
    for raw in text.splitlines():
        line = raw.split(";", 1)[0] if '"' not in raw else raw
        m = _MODULE.match(line)
        if m:
            config = bytes(int(x.strip(), 0) for x in m.group(2).split(",") if x.strip())
            module = module or (m.group(1), config)
            continue
        m = _LINE.match(line)
        if m:
            fields[m.group(1)] = m.group(2)
    if module is None or "Ident_Number" not in fields:
        raise ValueError("GSD: Ident_Number and one Module are required")
    rates = tuple(b for b, k in _BAUD_KEYS.items() if fields.get(f"{k}_supp", "0").strip() == "1")
    tsdr = {b: int(fields[f"MaxTsdr_{_BAUD_KEYS[b]}"], 0) for b in rates if f"MaxTsdr_{_BAUD_KEYS[b]}" in fields}
    return GsdFacts(
        ident_number=int(fields["Ident_Number"], 0),
        config=module[1],
        module_name=module[0],
        baud_rates=rates,
        max_tsdr=tsdr,
        max_diag_len=int(fields.get("Max_Diag_Data_Len", "6"), 0),
        user_prm_len=int(fields.get("User_Prm_Data_Len", "0"), 0),
        **{key.lower(): fields.get(key, '""').strip('"') for key in _TEXTS},
    )


@cache
def facts() -> GsdFacts:
    """The packaged GSD's facts (read once)."""
    return parse_facts(gsd_text())
