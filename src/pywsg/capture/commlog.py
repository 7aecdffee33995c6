"""The communication log (WSG Commander's "Communication Log" panel, command manual chapter 2).

Each frame is one entry: timestamp, direction (TX host -> gripper, RX gripper -> host), the wire
bytes in hex, and the decoded command ID, parameters (with units) and status, all read from the
protocol catalog through :func:`pywsg.protocol.decode.decode_frame`.

Text form (one line per frame, easy to grep)::

    12:00:01.234567 TX 21h PREPOSITION  AA AA AA 21 09 00 ...  flags=ABSOLUTE (0) width=50 mm ...
    12:00:01.235002 RX 21h PREPOSITION  AA AA AA 21 02 00 1A 00 67 CB  E_CMD_PENDING

JSON form: one object per line (JSON Lines) with ``time`` (Unix seconds), ``direction``
(``tx``/``rx``) and the fields of ``DecodedFrame.to_json()``; ``wsg log FILE`` reads it back.
"""

from __future__ import annotations

import collections
import datetime as _dt
import json
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Literal, TextIO

from ..protocol import Frame
from ..protocol.decode import DecodedFrame, decode_frame

__all__ = ["CommLog", "LogEntry", "TxRx", "entry_from_json", "format_line"]

TxRx = Literal["tx", "rx"]
_ARROW = {"tx": "TX", "rx": "RX"}


@dataclass
class LogEntry:
    """One logged frame. ``time`` is Unix time in seconds."""

    time: float
    direction: TxRx
    decoded: DecodedFrame

    @classmethod
    def from_frame(cls, direction: TxRx, frame: Frame, when: float | None = None) -> LogEntry:
        decoded = decode_frame(frame, "request" if direction == "tx" else "reply")
        return cls(time.time() if when is None else when, direction, decoded)

    def to_json(self) -> dict[str, Any]:
        return {"time": round(self.time, 6), **self.decoded.to_json(), "direction": self.direction}

    def line(self, hex_width: int = 0) -> str:
        return format_line(self, hex_width)


def wall_clock(t: float) -> str:
    """Unix seconds as local time of day with microseconds, ``19:44:34.052109`` (every log's style)."""
    return _dt.datetime.fromtimestamp(t).strftime("%H:%M:%S.%f")


def summary(decoded: DecodedFrame) -> str:
    """Status and parameters in one short string."""
    parts: list[str] = []
    if decoded.status is not None:
        parts.append(decoded.status)
    parts.extend(f"{v.name}={v.text}" for v in decoded.values)
    if decoded.error:
        parts.append(f"error: {decoded.error}")
    if decoded.checksum_ok is False:
        parts.append(f"CHECKSUM WRONG (expected {decoded.checksum_expected:04X}h)")
    return "  ".join(parts)


def format_line(entry: LogEntry, hex_width: int = 0) -> str:
    """One text line for ``entry``; ``hex_width`` pads the hex column (0: no padding)."""
    d = entry.decoded
    cid = f"{d.command_id:02X}h" if d.command_id is not None else "--"
    hexed = d.raw.hex(" ").upper()
    return (f"{wall_clock(entry.time)} {_ARROW[entry.direction]} {cid} {d.command:<24} "
            f"{hexed:<{hex_width}}  {summary(d)}").rstrip()


def entry_from_json(obj: dict[str, Any]) -> LogEntry:
    """Rebuild an entry from a JSON log line (re-decoded from its hex, so old logs get new decoders)."""
    from ..protocol.decode import decode_bytes, parse_hex

    direction: TxRx = "tx" if obj.get("direction") == "tx" else "rx"
    frames = decode_bytes(parse_hex(obj["hex"]), "request" if direction == "tx" else "reply")
    return LogEntry(float(obj["time"]), direction, frames[0])


class CommLog:
    """A sink for frames: writes text lines and/or JSON lines, and calls listeners.

    ``record(direction, frame)`` is what a transport tap calls for every frame it sends or receives.
    ``entries`` keeps only the last ``keep`` entries (a long capture streams to the files, not to
    memory). Thread-safe (the sync driver runs its loop in another thread).
    """

    def __init__(self, text: TextIO | None = None, jsonl: TextIO | None = None, keep: int = 1000) -> None:
        self.text = text
        self.jsonl = jsonl
        self.entries: collections.deque[LogEntry] = collections.deque(maxlen=keep)
        self.listeners: list[Callable[[LogEntry], None]] = []
        self._lock = threading.Lock()

    @classmethod
    def to_stderr(cls) -> CommLog:
        return cls(text=sys.stderr)

    def record(self, direction: TxRx, frame: Frame, when: float | None = None) -> LogEntry:
        entry = LogEntry.from_frame(direction, frame, when)
        with self._lock:
            self.entries.append(entry)
            if self.text is not None:
                self.text.write(entry.line() + "\n")
                self.text.flush()
            if self.jsonl is not None:
                self.jsonl.write(json.dumps(entry.to_json(), ensure_ascii=False) + "\n")
                self.jsonl.flush()
            for fn in self.listeners:
                fn(entry)
        return entry

    def note(self, direction: TxRx, message: str, when: float | None = None) -> None:
        """A stream problem (bad checksum, skipped bytes) in the log."""
        t = time.time() if when is None else when
        with self._lock:
            if self.text is not None:
                self.text.write(f"{wall_clock(t)} {_ARROW[direction]} -- {message}\n")
                self.text.flush()
            if self.jsonl is not None:
                self.jsonl.write(json.dumps({"time": round(t, 6), "direction": direction, "error": message}) + "\n")
                self.jsonl.flush()

    def hook(self, entry: Any) -> None:
        """Adapter for the driver's ``on_frame`` hook (``pywsg.client.commlog.CommEntry``)."""
        direction: TxRx = "tx" if entry.direction == "tx" else "rx"
        if entry.frame is not None:
            self.record(direction, entry.frame, entry.time)
        elif entry.error is not None:
            self.note(direction, entry.error.message, entry.time)
