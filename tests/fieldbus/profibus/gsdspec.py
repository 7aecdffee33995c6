"""A GSD file checked by the rules of the GSD specification (PROFIBUS guideline "Specification for
PROFIBUS Device Description and Device Integration, Volume 1: GSD") as configuration tools apply them,
written for the tests independently of pyprofibus's parser and of the slave's own reader.

Rules checked (a slave's file, DP-V0):

- text: ISO 8859-1; here every character printable ASCII (or TAB), the portable subset every tool
  reads; lines of at most 80 characters; a backslash at the end continues a line;
- the first statement is ``#Profibus_DP``; comments start with ``;``;
- a statement is ``Keyword = Value``, ``Keyword(n) = Value`` (``Unit_Diag_Bit(n)``), or a
  ``Module = "Name" identifiers`` … ``EndModule`` block; keywords as the specification spells them
  (compared without case, as the specification allows);
- value types: Visible-String(n) in double quotes with at most n characters, Unsigned8/16 in range,
  Boolean 0 or 1; ``Slave_Family`` a number with ``@``-separated sub-family names;
- mandatory keywords present; each ``<rate>_supp = 1`` has its ``MaxTsdr_<rate>``; a compact station
  (``Modular_Station = 0``) has exactly one module.
"""

from __future__ import annotations

import re

MAX_LINE = 80
_RATES = ("9.6", "19.2", "31.25", "45.45", "93.75", "187.5", "500", "1.5M", "3M", "6M", "12M")

# Keyword → type: "s<n>" Visible-String(n), "u8"/"u16" Unsigned, "b" Boolean, "family", "diag".
_TYPES: dict[str, str] = {
    "GSD_Revision": "u8", "Vendor_Name": "s32", "Model_Name": "s32", "Revision": "s32",
    "Revision_Number": "u8", "Ident_Number": "u16", "Protocol_Ident": "u8", "Station_Type": "u8",
    "FMS_supp": "b", "Hardware_Release": "s32", "Software_Release": "s32", "Redundancy": "b",
    "Repeater_Ctrl_Sig": "u8", "24V_Pins": "u8", "Implementation_Type": "s32", "Bitmap_Device": "s8",
    "Bitmap_Diag": "s8", "Bitmap_SF": "s8", "Freeze_Mode_supp": "b", "Sync_Mode_supp": "b",
    "Auto_Baud_supp": "b", "Set_Slave_Add_supp": "b", "User_Prm_Data_Len": "u8",
    "Max_User_Prm_Data_Len": "u8", "Min_Slave_Intervall": "u16", "Modular_Station": "b",
    "Max_Module": "u8", "Max_Input_Len": "u8", "Max_Output_Len": "u8", "Max_Data_Len": "u16",
    "Fail_Safe": "b", "Max_Diag_Data_Len": "u8", "Slave_Family": "family", "Family_Name": "s32",
    "OrderNumber": "s32", "Info_Text": "s256", "Periphery": "s32", "Unit_Diag_Bit": "diag",
    "Unit_Diag_Not_Bit": "diag", "Unit_Diag_Bit_Help": "diag256",
}
_TYPES.update({f"{r}_supp": "b" for r in _RATES})
_TYPES.update({f"MaxTsdr_{r}": "u16" for r in _RATES})
_CANON = {k.lower(): k for k in _TYPES}
_MANDATORY = ("GSD_Revision", "Vendor_Name", "Model_Name", "Revision", "Ident_Number", "Protocol_Ident",
              "Station_Type", "Hardware_Release", "Software_Release", "Slave_Family",
              "Min_Slave_Intervall", "Max_Diag_Data_Len", "Modular_Station")
_STATEMENT = re.compile(r"^([A-Za-z0-9_.]+)(?:\((\d+)\))?\s*=\s*(.*)$")
_MODULE = re.compile(r'^Module\s*=\s*"([^"]*)"\s+(.+)$', re.IGNORECASE)
_STRING = re.compile(r'^"([^"]*)"$')


def check(data: bytes) -> tuple[dict[str, str], list[str]]:
    """(the statements by canonical keyword, the rule violations found) for the GSD file ``data``."""
    problems: list[str] = []
    text = data.decode("latin-1")
    lines = text.replace("\r\n", "\n").split("\n")
    for n, line in enumerate(lines, 1):
        bad = sorted({c for c in line if not (" " <= c <= "~" or c == "\t")})
        if bad:
            problems.append(f"line {n}: characters outside printable ASCII: {''.join(bad)!r}")
        if len(line) > MAX_LINE:
            problems.append(f"line {n}: {len(line)} characters (at most {MAX_LINE})")
    statements: list[tuple[int, str]] = []
    pending = ""
    for n, line in enumerate(lines, 1):
        body = _strip_comment(line).strip()
        if body.endswith("\\"):
            pending += body[:-1] + " "
            continue
        body, pending = (pending + body).strip(), ""
        if body:
            statements.append((n, body))
    if not statements or statements[0][1] != "#Profibus_DP":
        problems.append("the first statement is not #Profibus_DP")
    found: dict[str, str] = {}
    modules: list[str] = []
    in_module = False
    for n, body in statements[1:]:
        module = _MODULE.match(body)
        if module:
            if in_module:
                problems.append(f"line {n}: Module inside a module")
            in_module = True
            name, ids = module.groups()
            modules.append(name)
            if len(name) > 32:
                problems.append(f"line {n}: module name of {len(name)} characters (at most 32)")
            for ident in ids.split(","):
                if not _unsigned(ident.strip(), 0xFF):
                    problems.append(f"line {n}: configuration identifier {ident.strip()!r} is not a byte")
            continue
        if body.lower() == "endmodule":
            if not in_module:
                problems.append(f"line {n}: EndModule without Module")
            in_module = False
            continue
        m = _STATEMENT.match(body)
        if m is None:
            problems.append(f"line {n}: not a statement: {body!r}")
            continue
        key, index, value = m.groups()
        canon = _CANON.get(key.lower())
        if canon is None:
            problems.append(f"line {n}: unknown keyword {key!r}")
            continue
        kind = _TYPES[canon]
        if (index is not None) != kind.startswith("diag"):
            problems.append(f"line {n}: {key} {'needs' if kind.startswith('diag') else 'takes no'} a bit number")
            continue
        if index is not None and not _unsigned(index, 0xFFFF):
            problems.append(f"line {n}: bit number {index} is not Unsigned16")
        problem = _value_problem(kind, value)
        if problem:
            problems.append(f"line {n}: {key}: {problem}")
        found[canon if index is None else f"{canon}({index})"] = value
    if in_module:
        problems.append("a Module without EndModule")
    for key in _MANDATORY:
        if key not in found:
            problems.append(f"mandatory keyword {key} missing")
    for rate in _RATES:
        if found.get(f"{rate}_supp") == "1" and f"MaxTsdr_{rate}" not in found:
            problems.append(f"{rate}_supp = 1 without MaxTsdr_{rate}")
    if found.get("Modular_Station") == "0" and len(modules) != 1:
        problems.append(f"a compact station (Modular_Station = 0) with {len(modules)} modules")
    return found, problems


def _strip_comment(line: str) -> str:
    """The line without its comment (a ``;`` outside double quotes)."""
    quoted = False
    for i, c in enumerate(line):
        if c == '"':
            quoted = not quoted
        elif c == ";" and not quoted:
            return line[:i]
    return line


def _unsigned(text: str, top: int) -> bool:
    try:
        value = int(text, 16) if text.lower().startswith("0x") else int(text)
    except ValueError:
        return False
    return 0 <= value <= top


def _value_problem(kind: str, value: str) -> str | None:
    if kind in ("u8", "u16"):
        return None if _unsigned(value, 0xFF if kind == "u8" else 0xFFFF) else f"{value!r} is not {kind}"
    if kind == "b":
        return None if value in ("0", "1") else f"{value!r} is not a Boolean (0 or 1)"
    if kind == "family":
        number, *subs = value.split("@")
        if not _unsigned(number.strip(), 0xFF):
            return f"family {number!r} is not Unsigned8"
        long = [s for s in subs if len(s) > 32]
        return f"sub-family names over 32 characters: {long}" if long else None
    limit = {"diag": 32, "diag256": 256}.get(kind) or int(kind[1:])
    m = _STRING.match(value)
    if m is None:
        return f"{value!r} is not a quoted Visible-String"
    if len(m.group(1)) > limit:
        return f"text of {len(m.group(1))} characters (at most {limit}): {m.group(1)!r}"
    return None
