"""What both shells share: reply interpretation, error construction, stream naming."""

from __future__ import annotations

from typing import Any, TypeVar, cast

from ..errors import BadChecksumReply, ConnectionLostError, ProtocolError, WsgError, error_for
from ..protocol import CATALOG, Command, Frame, Status, SystemFlag, crc16
from .calls import AUTO_UPDATE_IDS, STREAM_NAMES, Call, decode_sample
from .types import Reply, Sample

T = TypeVar("T")

DEFAULT_TIMEOUT = 1.0  # s for an immediate reply
DEFAULT_MOTION_TIMEOUT = 60.0  # s for the final frame of a motion


def status_of(frame: Frame) -> Status | int:
    try:
        return frame.status
    except ValueError:
        raise ProtocolError(Status.E_CMD_FORMAT_ERROR, frame.command_id, "reply without a status code",
                            from_device=False) from None


def frame_from(data: bytes | bytearray | memoryview, verify: bool) -> Frame | None:
    """Fast path: ``data`` is exactly one whole frame with a good CRC (the usual single reply per
    read). None: let the incremental parser handle it (partial, several, or bad frames)."""
    n = len(data)
    if n < 8 or data[0] != 0xAA or data[1] != 0xAA or data[2] != 0xAA or n != 8 + (data[4] | data[5] << 8):
        return None
    if verify and crc16(data[:-2]) != data[-2] | data[-1] << 8:
        return None
    return Frame(data[3], bytes(data[6:-2]))


def is_success(frame: Frame) -> bool:
    p = frame.payload
    return len(p) >= 2 and p[0] == 0 and p[1] == 0


def needs_flags(call: Call[Any], status: Status | int) -> bool:
    """Errors where the system flags tell the user what to do (FAST STOP? blocked? referenced?)."""
    return call.motion or status in (Status.E_ACCESS_DENIED, Status.E_CMD_FAILED)


def decode_success(call: Call[T], frame: Frame) -> T:
    """The result of an E_SUCCESS reply. Raises ProtocolError on a reply of the wrong shape."""
    if call.raw:
        return cast(T, Reply(frame.command_id, status_of(frame), frame.params))
    if call.fast is not None:
        try:
            return call.fast(frame.payload)
        except ValueError as exc:
            raise ProtocolError(Status.E_CMD_FORMAT_ERROR, call.command_id, f"malformed reply: {exc}",
                                from_device=False) from None
    spec = CATALOG.get(call.command_id)
    if spec is None or not spec.reply:
        return call.decode({})
    try:
        _, values = spec.decode_reply(frame.payload)
    except ValueError as exc:
        raise ProtocolError(Status.E_CMD_FORMAT_ERROR, call.command_id, f"malformed reply: {exc}",
                            from_device=False) from None
    return call.decode(values)


def raise_for(call: Call[Any], frame: Frame, flags: SystemFlag | None) -> WsgError:
    return error_for(status_of(frame), call.command_id, flags)


def bad_checksum(cid: int) -> BadChecksumReply:
    return BadChecksumReply(Status.E_CHECKSUM_ERROR, cid, "reply with a bad CRC from the gripper was rejected",
                            from_device=False)


def lost(detail: str) -> Any:
    def make(cid: int) -> ConnectionLostError:
        return ConnectionLostError(detail, cid)
    return make


def stream_id(what: str | int) -> Command:
    """``"width"`` / ``Command.GET_OPENING_WIDTH`` / ``0x43`` -> Command; only auto-update IDs."""
    if isinstance(what, str):
        try:
            return STREAM_NAMES[what]
        except KeyError:
            raise ValueError(f"unknown stream {what!r}; use one of {', '.join(STREAM_NAMES)}") from None
    cmd = Command(what)
    if cmd not in AUTO_UPDATE_IDS:
        raise ValueError(f"{cmd.name} has no auto-update")
    return cmd


def sample_of(frame: Frame, now: float) -> Sample | None:
    spec = CATALOG[frame.command_id]
    try:
        _, values = spec.decode_reply(frame.payload)
    except ValueError:
        return None
    return Sample(Command(frame.command_id), decode_sample(frame.command_id, values), now)
