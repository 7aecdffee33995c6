"""What both shells share: reply interpretation, error construction, stream naming."""

from __future__ import annotations

from typing import Any, TypeVar, cast

from ..errors import BadChecksumReply, ConnectionLostError, ProtocolError, WsgError, error_for
from ..protocol import CATALOG, Command, Frame, Status, SystemFlag
from ..protocol.parser import MaxPayload, whole_frame
from .calls import AUTO_UPDATE_IDS, STREAM_NAMES, Call, decode_sample
from .reconnect import ReconnectPolicy as ReconnectPolicy  # it lived here before 0.4
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


# Verified short frames by their exact bytes: a state read answers the same bytes until the state
# changes, so the CRC and the Frame are computed once. Only frames whose checksum was checked go in
# (a client that does not verify never reads from it); bounded, cleared when full.
_FRAMES: dict[bytes, Frame] = {}
_FRAMES_MAX = 1024
_CACHED_FRAME_LEN = 64


def frame_from(data: bytes, verify: bool, max_payload: MaxPayload) -> Frame | None:
    """Fast path: ``data`` is exactly one whole frame with a good CRC (the usual single reply per
    read). None: let the incremental parser handle it (partial, several, or bad frames)."""
    if verify:
        frame = _FRAMES.get(data)
        if frame is not None:
            return frame
    frame = whole_frame(data, verify, max_payload)
    if frame is not None and verify and len(data) <= _CACHED_FRAME_LEN:
        if len(_FRAMES) >= _FRAMES_MAX:
            _FRAMES.clear()
        _FRAMES[data] = frame
    return frame


def is_success(frame: Frame) -> bool:
    p = frame.payload
    return len(p) >= 2 and p[0] == 0 and p[1] == 0


def needs_flags(call: Call[Any], status: Status | int) -> bool:
    """Errors where the system flags tell the user what to do (FAST STOP? blocked? referenced?)."""
    return call.motion or status in (Status.E_ACCESS_DENIED, Status.E_CMD_FAILED)


def decode_success(call: Call[T], frame: Frame) -> T:
    """The result of an E_SUCCESS reply. Raises ProtocolError on a reply of the wrong shape."""
    memo = call.memo
    if memo is not None:  # immutable results of fixed layouts, by payload
        r = memo.get(frame.payload)
        if r is not None:
            return r
    if call.raw:
        return cast(T, Reply(frame.command_id, status_of(frame), frame.params))
    if call.fast is not None:
        try:
            r = call.fast(frame.payload)
        except ValueError as exc:
            raise ProtocolError(Status.E_CMD_FORMAT_ERROR, call.command_id, f"malformed reply: {exc}",
                                from_device=False) from None
        if memo is not None:
            if len(memo) >= _MEMO_MAX:
                memo.clear()
            memo[frame.payload] = r
        return r
    spec = CATALOG.get(call.command_id)
    if spec is None or not spec.reply:
        return call.decode({})
    try:
        _, values = spec.decode_reply(frame.payload)
    except ValueError as exc:
        raise ProtocolError(Status.E_CMD_FORMAT_ERROR, call.command_id, f"malformed reply: {exc}",
                            from_device=False) from None
    return call.decode(values)


_MEMO_MAX = 512


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
