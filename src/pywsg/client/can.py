"""CAN for the driver (``can://CHANNEL?interface=socketcan&...``): what the blocking and the asyncio
CAN transports (``_sync/can_transport.py``, ``_async/can_transport.py``) share.

**Inferred mapping** (the manuals name CAN as an interface, 000 §1.1, but do not specify it; see
docs/driver.md "CAN"): the binary protocol's byte stream, cut into CAN data frames of up to 8 bytes
(all but the last full), requests on ``request_id`` (default 01h), replies and auto-updates on
``reply_id`` (default 02h), standard 11-bit identifiers. The receiver reassembles with the ordinary
frame parser, as on a serial line: the frame header carries the length, the CRC checks the result.
A lost or reordered fragment makes a frame fail its CRC (the call fails with BadChecksumReply, or
times out); the parser resynchronises on the next preamble, so the next call works.

Frames with other identifiers, remote and error frames are ignored: the bus is opened with an
acceptance filter (in the kernel for socketcan, in python-can for the others) and each frame's
identifier is checked again here, so a bus flooded with foreign traffic costs a bounded amount of
work per frame and never reaches the parser. Needs python-can (``pip install 'pywsg[can]'``).
"""

from __future__ import annotations

from typing import Any

from .url import Endpoint

CAN_DLEN = 8  # data bytes of a classic CAN frame
DRAIN = 256  # CAN frames read at once before the bytes go to the parser (a 1 KiB frame is 130)


def _value(raw: str) -> Any:
    """A URL option for ``can.Bus``: int (decimal or 0x..), bool, else the string."""
    low = raw.lower()
    if low in ("true", "false"):
        return low == "true"
    try:
        return int(raw, 0)
    except ValueError:
        return raw


def open_bus(ep: Endpoint) -> Any:
    """A python-can bus for ``ep`` with an acceptance filter for the reply identifier.

    No ``interface`` in the URL: python-can's own configuration decides (``~/.canrc``,
    ``CAN_INTERFACE``), as in any python-can program. Raises OSError when it cannot be opened.
    """
    try:
        import can
    except ImportError as exc:
        raise ConnectionRefusedError("can:// needs python-can: pip install 'pywsg[can]'") from exc
    kwargs: dict[str, Any] = {k: _value(v) for k, v in ep.can_options}
    kwargs["channel"] = ep.path
    if ep.interface:
        kwargs["interface"] = ep.interface
    if ep.bitrate:
        kwargs["bitrate"] = ep.bitrate
    mask = 0x1FFFFFFF if ep.extended else 0x7FF
    kwargs["can_filters"] = [{"can_id": ep.reply_id, "can_mask": mask, "extended": ep.extended}]
    try:
        return can.Bus(**kwargs)
    except (can.CanError, ValueError, TypeError, NotImplementedError, ImportError) as exc:
        raise ConnectionRefusedError(f"cannot open CAN channel {ep.path!r}: {exc}") from exc


def fragments(data: bytes, can_id: int, extended: bool) -> list[Any]:
    """``data`` as CAN data frames of up to 8 bytes on ``can_id``."""
    import can

    return [can.Message(arbitration_id=can_id, data=data[i : i + CAN_DLEN], is_extended_id=extended)
            for i in range(0, len(data), CAN_DLEN)]


def accepts(msg: Any, ep: Endpoint) -> bool:
    """A data frame on the reply identifier (filters may be emulated loosely by an interface)."""
    return (msg.arbitration_id == ep.reply_id and not msg.is_remote_frame and not msg.is_error_frame
            and bool(msg.is_extended_id) == ep.extended)


def send(bus: Any, ep: Endpoint, data: bytes, timeout: float) -> None:
    """``data`` as fragments on the request identifier; ``timeout`` in s per CAN frame."""
    import can

    try:
        for msg in fragments(data, ep.request_id, ep.extended):
            bus.send(msg, timeout)
    except can.CanError as exc:
        raise ConnectionResetError(f"CAN send on {ep.path!r} failed: {exc}") from exc
