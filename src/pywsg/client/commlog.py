"""Communication log: every frame in and out, timestamped, decoded through the catalog on demand.

Install a hook with ``gripper.on_frame = fn`` (``fn(entry: CommEntry)``), or enable the standard
``logging`` logger ``pywsg.client.frames`` at DEBUG. Decoding is lazy: ``entry.text`` builds the
line only when asked for, so a hook that stores entries costs little.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import dataclass

from ..protocol import CATALOG, Frame, ParseError, Status
from ..protocol.catalog import format_value

frame_log = logging.getLogger("pywsg.client.frames")

TX = "tx"
RX = "rx"


def describe(frame: Frame, direction: str) -> str:
    """One human line for a frame: ``41h GET_GRIPPER_STATE reply E_SUCCESS state=HOLDING (4)``."""
    cid = frame.command_id
    spec = CATALOG.get(cid)
    name = spec.name if spec else "UNKNOWN"
    head = f"{cid:02X}h {name}"
    if direction == TX:
        if spec is None:
            return f"{head} request {frame.payload.hex(' ').upper() or '(no payload)'}"
        try:
            values = spec.decode_request(frame.payload)
        except ValueError as exc:
            return f"{head} request (malformed: {exc}) {frame.payload.hex(' ').upper()}"
        fields = {f.name: f for f in spec.request}
        args = " ".join(f"{k}={format_value(v, fields[k])}" for k, v in values.items())
        return f"{head} request {args}".rstrip()
    if len(frame.payload) < 2:
        return f"{head} reply (no status) {frame.payload.hex(' ').upper()}"
    status = frame.status
    sname = status.name if isinstance(status, Status) else f"status {status}"
    if spec is None or status != Status.E_SUCCESS:
        rest = frame.params.hex(" ").upper()
        return f"{head} reply {sname} {rest}".rstrip()
    try:
        _, values = spec.decode_reply(frame.payload)
    except ValueError as exc:
        return f"{head} reply {sname} (malformed: {exc})"
    fields = {f.name: f for f in spec.reply}
    args = " ".join(f"{k}={format_value(v, fields[k])}" for k, v in values.items())
    return f"{head} reply {sname} {args}".rstrip()


@dataclass(frozen=True, slots=True)
class CommEntry:
    """One logged frame. ``time``: ``time.time()`` (s since the epoch); ``direction``: "tx" or "rx";
    ``frame``: the frame (None for a parse error); ``error``: the parser's event for bad input
    (checksum mismatch, skipped garbage)."""

    time: float
    direction: str
    frame: Frame | None
    error: ParseError | None = None

    @property
    def text(self) -> str:
        if self.frame is None:
            return f"{self.direction} {self.error.message if self.error else '?'}"
        return f"{self.direction} {describe(self.frame, self.direction)}"

    @property
    def hex(self) -> str:
        return self.frame.hex() if self.frame is not None else ""

    def __str__(self) -> str:
        stamp = time.strftime("%H:%M:%S", time.localtime(self.time)) + f".{int(self.time * 1000) % 1000:03d}"
        return f"{stamp} {self.text}"


CommHook = Callable[[CommEntry], None]


class CommLog:
    """Fans frames out to the hook and the DEBUG logger; cheap when neither listens."""

    __slots__ = ("hook",)

    def __init__(self) -> None:
        self.hook: CommHook | None = None

    @property
    def active(self) -> bool:
        return self.hook is not None or frame_log.isEnabledFor(logging.DEBUG)

    def frame(self, direction: str, frame: Frame) -> None:
        entry = CommEntry(time.time(), direction, frame)
        self._emit(entry)

    def error(self, direction: str, error: ParseError) -> None:
        self._emit(CommEntry(time.time(), direction, None, error))

    def _emit(self, entry: CommEntry) -> None:
        if frame_log.isEnabledFor(logging.DEBUG):
            frame_log.debug("%s", entry.text)
        hook = self.hook
        if hook is not None:
            try:
                hook(entry)
            except Exception:  # a broken hook must not break the connection
                frame_log.exception("communication log hook failed")
