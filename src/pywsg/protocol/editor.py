"""The WSG Commander's Custom Command Editor syntax (command manual, chapter 2).

Sans-IO, so both front ends read one parser: ``wsg send``/``wsg loop`` and the web Commander
(``wsg commander``), which marks a bad item at its place in the line (``PayloadSyntaxError.start``).

A payload is a list of items separated by blanks or commas:

* decimal bytes ``0`` .. ``255`` (``-128`` .. ``-1`` are taken as signed bytes);
* hexadecimal bytes ``0x20`` (``0x00`` .. ``0xFF``);
* floating point values followed by ``f``, e.g. ``150.0f``: IEEE-754 float32, little endian,
  the wire format of every mm, mm/s, mm/s² and N parameter;
* text in double quotes, e.g. ``"ack"``: its ASCII bytes (``\\"``, ``\\\\`` and ``\\xNN`` escapes);

and, beyond the manual, little-endian integers with a width suffix: ``1000u16``, ``-5i16``, ``7u32``
(the manual's 16- and 32-bit fields, e.g. the PERIOD_MS of auto-update commands).

The command ID is a decimal number, ``0x21``, ``21h`` (the manual's spelling) or a catalog name
(``PREPOSITION``, case-insensitive).
"""

from __future__ import annotations

import re
import struct
from collections.abc import Iterable
from dataclasses import dataclass

from .catalog import CATALOG, Command
from .frame import encode_frame

__all__ = [
    "Item", "Packet", "PayloadSyntaxError", "build_packet", "parse_command_id", "parse_items", "parse_payload",
    "tokenize", "tokens",
]


class PayloadSyntaxError(ValueError):
    """An item of the payload (or the ID) does not follow the editor syntax.

    ``start``/``end``: the characters of the payload text the error is about (``text[start:end]``),
    when known; a front end marks them (the web Commander underlines the token).
    """

    def __init__(self, message: str, start: int | None = None, end: int | None = None) -> None:
        super().__init__(message)
        self.start = start
        self.end = end


@dataclass(frozen=True)
class Item:
    """One payload item: its text, where it stands in the line (``start``/``end`` characters) and its bytes."""

    text: str
    start: int
    end: int
    data: bytes


_INT_SUFFIX = {"u8": "<B", "i8": "<b", "u16": "<H", "i16": "<h", "u32": "<I", "i32": "<i"}
_INT_RE = re.compile(r"[+-]?(?:0[xX][0-9a-fA-F]+|\d+)")
_WIDE_RE = re.compile(r"(?P<num>[+-]?(?:0[xX][0-9a-fA-F]+|\d+))(?P<suffix>[ui](?:8|16|32))", re.IGNORECASE)
_FLOAT_RE = re.compile(r"(?P<num>[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?)[fF]")
_ESCAPE_RE = re.compile(r"\\(x[0-9a-fA-F]{2}|.)", re.DOTALL)


def tokenize(text: str) -> list[str]:
    """Split a payload line into items: blanks/commas separate, ``"..."`` is one item."""
    return [tok for tok, _ in tokens(text)]


def tokens(text: str) -> list[tuple[str, int]]:
    """The items of a payload line with the column (0-based) each starts at."""
    found: list[tuple[str, int]] = []
    i, n = 0, len(text)
    while i < n:
        c = text[i]
        if c.isspace() or c == ",":
            i += 1
            continue
        if c == '"':
            j = i + 1
            while j < n and text[j] != '"':
                j += 2 if text[j] == "\\" else 1
            if j >= n:
                raise PayloadSyntaxError(f"unterminated text starting at column {i + 1}: {text[i:]!r}", i, n)
            found.append((text[i : j + 1], i))
            i = j + 1
            continue
        j = i
        while j < n and not text[j].isspace() and text[j] not in ',"':
            j += 1
        found.append((text[i:j], i))
        i = j
    return found


def _text_bytes(token: str) -> bytes:
    body = token[1:-1]

    def unescape(m: re.Match[str]) -> str:
        seq = m.group(1)
        if seq.startswith("x") and len(seq) == 3:
            return chr(int(seq[1:], 16))
        if seq in ('"', "\\"):
            return seq
        raise PayloadSyntaxError(f"unknown escape \\{seq} in {token}")

    raw = _ESCAPE_RE.sub(unescape, body)
    try:
        return raw.encode("latin-1")
    except UnicodeEncodeError:
        raise PayloadSyntaxError(f"text {token} holds characters outside one byte (use ASCII)") from None


def parse_item(token: str) -> bytes:
    """Bytes of one payload item."""
    if len(token) >= 2 and token[0] == token[-1] == '"':
        return _text_bytes(token)
    if _INT_RE.fullmatch(token):
        is_hex = token.lstrip("+-")[:2].lower() == "0x"
        value = int(token, 16 if is_hex else 10)
        if is_hex:
            if token.startswith(("-", "+")) or value > 0xFF:
                raise PayloadSyntaxError(
                    f"{token}: a hex item is one byte 0x00..0xFF; write wider values byte by byte "
                    "(low byte first) or with a suffix such as 0x1234u16"
                )
            return bytes([value])
        if -128 <= value <= 255:
            return bytes([value & 0xFF])
        raise PayloadSyntaxError(
            f"{token}: a decimal item is one byte (0..255, or -128..-1); for wider values add a suffix "
            f"such as {token}u16 or {token}u32, for floats an f ({token}.0f)"
        )
    m = _FLOAT_RE.fullmatch(token)
    if m:
        value_f = float(m.group("num"))
        try:
            return struct.pack("<f", value_f)
        except OverflowError:
            raise PayloadSyntaxError(f"{token}: out of float32 range") from None
    m = _WIDE_RE.fullmatch(token)
    if m:
        fmt = _INT_SUFFIX[m.group("suffix").lower()]
        try:
            return struct.pack(fmt, int(m.group("num"), 0))
        except struct.error:
            raise PayloadSyntaxError(f"{token}: out of range for {m.group('suffix')}") from None
    hint = ""
    if re.fullmatch(r"[+-]?(?:\d+\.\d*|\.\d+)(?:[eE][+-]?\d+)?", token):
        hint = f" (floats need an f: {token}f)"
    elif token.replace("_", "").isalnum() and not token[0].isdigit():
        hint = f' (text needs double quotes: write \'"{token}"\' in the shell)'
    raise PayloadSyntaxError(
        f"cannot read payload item {token!r}{hint}: use decimal bytes (32), hex bytes (0x20), "
        'floats (150.0f) or quoted text ("ack")'
    )


def parse_items(text: str) -> list[Item]:
    """Each item of a payload line with its place and bytes; a bad item raises
    :class:`PayloadSyntaxError` carrying its place (``start``/``end``)."""
    out: list[Item] = []
    for tok, start in tokens(text):
        try:
            data = parse_item(tok)
        except PayloadSyntaxError as exc:
            raise PayloadSyntaxError(str(exc), start, start + len(tok)) from None
        out.append(Item(tok, start, start + len(tok), data))
    return out


def parse_payload(items: str | Iterable[str]) -> bytes:
    """Payload bytes from the editor syntax: one string, or several (joined with blanks)."""
    text = items if isinstance(items, str) else " ".join(items)
    return b"".join(item.data for item in parse_items(text))


def parse_command_id(text: str) -> int:
    """Command ID from ``33``, ``0x21``, ``21h`` or a catalog name (``preposition``)."""
    t = text.strip()
    try:
        if re.fullmatch(r"[0-9a-fA-F]{1,2}[hH]", t):
            value = int(t[:-1], 16)
        elif re.fullmatch(r"0[xX][0-9a-fA-F]+", t):
            value = int(t, 16)
        elif re.fullmatch(r"\d+", t):
            value = int(t, 10)
        else:
            value = int(Command[t.upper().replace("-", "_")])
    except KeyError:
        names = ", ".join(s.name.lower() for s in CATALOG.values())
        raise PayloadSyntaxError(
            f"unknown command {text!r}; use an ID (0x21, 21h, 33) or one of: {names}"
        ) from None
    if not 0 <= value <= 0xFF:
        raise PayloadSyntaxError(f"command ID {text} is not a byte (0..255)")
    return value


@dataclass(frozen=True)
class Packet:
    """A packet assembled by the editor: what ``wsg send`` puts on the wire."""

    command_id: int
    payload: bytes

    @property
    def wire(self) -> bytes:
        """Whole frame: preamble, ID, SIZE, payload, CRC."""
        return encode_frame(self.command_id, self.payload)


def build_packet(command: str, payload: str | Iterable[str] = ()) -> Packet:
    """``build_packet("0x30", "150.0f")`` -> the frame the Commander's editor would show."""
    return Packet(parse_command_id(command), parse_payload(payload))
