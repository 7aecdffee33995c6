"""Human decoding of frames: what ``wsg decode`` and the communication log print.

Direction is a guess: a payload that fits the command's reply layout behind a known status code
is a reply; one that fits the request layout is a request. Values come from the catalog.
"""

from __future__ import annotations

import re
import struct
from dataclasses import dataclass, field
from typing import Any, Literal

from .catalog import CATALOG, CommandSpec, Value, format_value
from .crc import crc16
from .frame import HEADER_SIZE, OVERHEAD, PREAMBLE, Frame
from .parser import FrameParser, FrameTooLarge, GarbageSkipped
from .status import Status

Direction = Literal["request", "reply", "unknown"]
_TOKEN = re.compile(r"(?i)^(?:0x)?([0-9a-f]+)h?$")


def parse_hex(text: str) -> bytes:
    """Bytes from hex text: ``AA AA AA``, ``AAh AAh``, ``0xAA,0xAA``, ``aaaaaa`` (mixed freely).

    Raises ValueError naming the first token that is not hex.
    """
    out = bytearray()
    for token in re.split(r"[\s,;:]+", text.strip()):
        if not token:
            continue
        m = _TOKEN.match(token)
        if not m:
            raise ValueError(f"not a hex byte: {token!r}")
        digits = m.group(1)
        explicit = token.lower().startswith("0x") or token.lower().endswith("h")
        if explicit and len(digits) <= 2:
            out.append(int(digits, 16))
        elif len(digits) % 2:
            raise ValueError(f"odd number of hex digits in {token!r}")
        else:
            out += bytes.fromhex(digits)
    return bytes(out)


@dataclass
class DecodedValue:
    name: str
    value: Value
    unit: str
    text: str


@dataclass
class DecodedFrame:
    """One frame (or parse problem) as shown to a person."""

    raw: bytes
    command_id: int | None
    command: str
    direction: Direction
    checksum_ok: bool | None
    checksum_received: int | None = None
    checksum_expected: int | None = None
    status: str | None = None
    status_code: int | None = None
    status_meaning: str | None = None
    values: list[DecodedValue] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    error: str | None = None

    def to_json(self) -> dict[str, Any]:
        return {
            "hex": self.raw.hex(" ").upper(),
            "command_id": self.command_id,
            "command": self.command,
            "direction": self.direction,
            "checksum_ok": self.checksum_ok,
            "checksum_received": _hex4(self.checksum_received),
            "checksum_expected": _hex4(self.checksum_expected),
            "status": self.status,
            "status_code": self.status_code,
            "status_meaning": self.status_meaning,
            "params": {v.name: _jsonable(v.value) for v in self.values},
            "units": {v.name: v.unit for v in self.values if v.unit},
            "notes": self.notes,
            "error": self.error,
        }

    def lines(self) -> list[str]:
        """Plain text, one fact per line."""
        if self.error and self.command_id is None:
            return [f"error: {self.error}", f"  bytes: {self.raw.hex(' ').upper()}"]
        cid = f"{self.command_id:02X}h" if self.command_id is not None else "?"
        out = [f"{self.direction} {self.command} ({cid})"]
        out.append(f"  bytes: {self.raw.hex(' ').upper()}")
        if self.status is not None:
            out.append(f"  status: {self.status} ({self.status_code}): {self.status_meaning}")
        for v in self.values:
            out.append(f"  {v.name}: {v.text}")
        if self.checksum_ok is True:
            out.append(f"  checksum: OK ({self.checksum_received:04X}h)")
        elif self.checksum_ok is False:
            out.append(
                f"  checksum: WRONG, received {self.checksum_received:04X}h, expected {self.checksum_expected:04X}h"
            )
        if self.error:
            out.append(f"  error: {self.error}")
        out.extend(f"  note: {n}" for n in self.notes)
        return out


def _hex4(v: int | None) -> str | None:
    return None if v is None else f"{v:04X}"


def _jsonable(v: Value) -> Any:
    if isinstance(v, bytes):
        return v.hex(" ").upper()
    if isinstance(v, float):
        return round(v, 6)
    if hasattr(v, "name") and isinstance(v, int):
        return {"value": int(v), "name": str(format_value(v, _NOFIELD))}
    return v


class _NoField:
    unit = ""


_NOFIELD: Any = _NoField()


def _values(spec: CommandSpec, decoded: dict[str, Value], reply: bool) -> list[DecodedValue]:
    fields = spec.reply if reply else spec.request
    out = []
    for f in fields:
        if f.name in decoded:
            v = decoded[f.name]
            text = format_value(v, f)
            if f.name == "temperature" and isinstance(v, int):
                text = f"{v / 10:.1f} °C (raw {v})"
            out.append(DecodedValue(f.name, v, f.unit, text))
    return out


def decode_frame(
    frame: Frame, direction: Direction | None = None, checksum: tuple[int, int] | None = None
) -> DecodedFrame:
    """Decode one frame. ``direction`` None guesses it; ``checksum`` is (received, expected)."""
    raw = frame.encode() if checksum is None else _rebuild(frame, checksum[0])
    spec = CATALOG.get(frame.command_id)
    name = spec.name if spec else f"UNKNOWN_{frame.command_id:02X}h"
    ok = None if checksum is None else checksum[0] == checksum[1]
    d = DecodedFrame(raw, frame.command_id, name, "unknown", ok if checksum else True,
                     checksum[0] if checksum else crc16(raw[:-2]), checksum[1] if checksum else crc16(raw[:-2]))
    as_reply = _try_reply(spec, frame.payload)
    as_request = _try_request(spec, frame.payload)
    if direction is None:
        if as_reply is not None and (as_request is None or _status_plausible(frame.payload)):
            direction = "reply"
        elif as_request is not None:
            direction = "request"
        elif len(frame.payload) >= 2 and _status_plausible(frame.payload):
            direction = "reply"
        else:
            direction = "unknown"
    d.direction = direction
    if direction == "reply" and len(frame.payload) >= 2:
        code = frame.payload[0] | frame.payload[1] << 8
        d.status_code = code
        try:
            st = Status(code)
            d.status, d.status_meaning = st.name, st.description
        except ValueError:
            d.status, d.status_meaning = f"UNKNOWN_{code}", "not a status code of the manual"
        if as_reply is not None and spec is not None:
            d.values = _values(spec, as_reply, reply=True)
        elif len(frame.payload) > 2:
            params = frame.payload[2:]
            d.notes.append(f"parameters do not match the {name} reply layout: {params.hex(' ').upper()}")
            twin = _getter_twin(spec)
            if twin is not None:
                try:
                    values = twin.reply_layout.decode(params)
                except ValueError:
                    pass
                else:
                    # the manual's own example 3 labels a 30h reply "Get Acceleration" (31h)
                    d.notes.append(f"they fit the {twin.label} reply layout; shown as such")
                    d.values = _values(twin, values, reply=True)
            d.notes.extend(_guesses(params))
    elif direction == "request" and spec is not None and as_request is not None:
        d.values = _values(spec, as_request, reply=False)
    elif frame.payload:
        d.notes.append(f"payload: {frame.payload.hex(' ').upper()}")
        d.notes.extend(_guesses(frame.payload))
    if spec is None:
        d.notes.append("command ID not in the manual (on-board script command or unknown)")
    return d


def _getter_twin(spec: CommandSpec | None) -> CommandSpec | None:
    """GET_X for a SET_X command (same parameter, read back)."""
    if spec is None or not spec.name.startswith("SET_"):
        return None
    for other in CATALOG.values():
        if other.name == "GET_" + spec.name[4:]:
            return other
    return None


def _rebuild(frame: Frame, received: int) -> bytes:
    return frame.encode()[:-2] + struct.pack("<H", received)


def _status_plausible(payload: bytes) -> bool:
    return len(payload) >= 2 and payload[1] == 0 and payload[0] <= max(Status)


def _try_reply(spec: CommandSpec | None, payload: bytes) -> dict[str, Value] | None:
    if spec is None or not _status_plausible(payload):
        return None
    if payload[0] != Status.E_SUCCESS:
        return {} if len(payload) == 2 else None
    try:
        return spec.reply_layout.decode(payload[2:])
    except ValueError:
        return None


def _try_request(spec: CommandSpec | None, payload: bytes) -> dict[str, Value] | None:
    if spec is None:
        return None
    try:
        values = spec.request_layout.decode(payload)
    except ValueError:
        return None
    var = spec.request_layout.variable
    if var is not None and var.max_len and len(payload) - spec.request_layout.fixed_size > var.max_len:
        return None
    return values


def _guesses(params: bytes) -> list[str]:
    out = []
    if len(params) % 4 == 0 and params:
        floats = struct.unpack(f"<{len(params) // 4}f", params)
        out.append("as float32: " + ", ".join(f"{f:g}" for f in floats))
    if len(params) in (1, 2, 4):
        out.append(f"as integer: {int.from_bytes(params, 'little')}")
    if params and all(32 <= b < 127 for b in params):
        out.append(f"as text: {params.decode('ascii')!r}")
    return out


def decode_bytes(data: bytes, direction: Direction | None = None) -> list[DecodedFrame]:
    """Decode every frame in ``data``; report bad checksums, skipped bytes and a truncated tail.

    The parser runs with checksum verification off so a frame with a wrong CRC is still shown
    (with the expected value); offsets are tracked to read each frame's received checksum.
    """
    parser = FrameParser(verify_checksum=False)
    out: list[DecodedFrame] = []
    offset = 0
    for ev in parser.feed(data):
        if isinstance(ev, Frame):
            end = offset + len(ev.payload) + OVERHEAD
            raw = data[offset:end]
            received = raw[-2] | raw[-1] << 8
            out.append(decode_frame(ev, direction, (received, crc16(raw[:-2]))))
            offset = end
        elif isinstance(ev, GarbageSkipped):
            out.append(DecodedFrame(data[offset : offset + ev.count], None, "-", "unknown", None, error=ev.message))
            offset += ev.count
        elif isinstance(ev, FrameTooLarge):
            out.append(DecodedFrame(b"", ev.command_id, "-", "unknown", None, error=ev.message))
            offset += 1
        else:  # pragma: no cover - no other events without verification
            out.append(DecodedFrame(b"", None, "-", "unknown", None, error=ev.message))
    rest = parser.pending()
    if rest:
        out.append(_truncated(rest))
    return out


def _truncated(rest: bytes) -> DecodedFrame:
    cid = rest[3] if len(rest) > 3 else None
    need = OVERHEAD + (rest[4] | rest[5] << 8) if len(rest) >= HEADER_SIZE else None
    have = len(rest)
    msg = f"truncated frame: {have} bytes" + (f" of {need}" if need else "")
    if not rest.startswith(PREAMBLE[: len(rest)]) and not rest.startswith(PREAMBLE):
        msg = f"{have} trailing byte(s) that are not a frame"
    spec = CATALOG.get(cid) if cid is not None else None
    return DecodedFrame(rest, cid, spec.name if spec else "-", "unknown", None, error=msg)
