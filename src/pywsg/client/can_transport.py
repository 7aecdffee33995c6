"""CAN transports of the driver (``can://CHANNEL?interface=socketcan&...``), blocking and asyncio.

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

import asyncio
import threading
import time
from typing import Any

from .aio_transport import AsyncTransport, OnData, OnLost
from .sync_transport import SyncTransport
from .url import Endpoint

CAN_DLEN = 8  # data bytes of a classic CAN frame
_DRAIN = 256  # CAN frames read at once before the bytes go to the parser (a 1 KiB frame is 130)


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


def _send(bus: Any, ep: Endpoint, data: bytes, timeout: float) -> None:
    import can

    try:
        for msg in fragments(data, ep.request_id, ep.extended):
            bus.send(msg, timeout)
    except can.CanError as exc:
        raise ConnectionResetError(f"CAN send on {ep.path!r} failed: {exc}") from exc


class CanSyncTransport(SyncTransport):
    """Blocking: ``recv`` returns the bytes of the reply frames available (at least one CAN frame)."""

    def __init__(self, ep: Endpoint, timeout: float) -> None:
        self.ep = ep
        self.bus = open_bus(ep)
        self.peer = str(ep)
        self._send_timeout = timeout
        self.foreign = 0  # frames ignored (another identifier, remote, error)

    def send(self, data: bytes) -> None:
        _send(self.bus, self.ep, data, self._send_timeout)

    def recv(self, timeout: float) -> bytes:
        import can

        ep, bus = self.ep, self.bus
        deadline = time.monotonic() + timeout
        out = bytearray()
        try:
            msg = bus.recv(max(timeout, 0.0))
            while msg is not None:
                if accepts(msg, ep):
                    out += msg.data
                    if len(out) >= _DRAIN * CAN_DLEN:
                        break
                    msg = bus.recv(0)  # the frame's other fragments, already queued
                elif out:
                    msg = bus.recv(0)
                else:
                    self.foreign += 1
                    remaining = deadline - time.monotonic()
                    if remaining <= 0:
                        break
                    msg = bus.recv(remaining)
        except can.CanError as exc:
            raise ConnectionResetError(f"CAN receive on {ep.path!r} failed: {exc}") from exc
        return bytes(out)

    def close(self) -> None:
        try:
            self.bus.shutdown()
        except Exception:
            pass


class CanTransport(AsyncTransport):
    """asyncio: a python-can ``Notifier`` delivers the frames on the event loop (socketcan: through
    ``add_reader``; other interfaces: a reader thread)."""

    def __init__(self, ep: Endpoint, bus: Any, on_data: OnData, on_lost: OnLost,
                 loop: asyncio.AbstractEventLoop) -> None:
        import can

        self.ep = ep
        self.bus = bus
        self.peer = str(ep)
        self.foreign = 0
        self._on_data = on_data
        self._on_lost = on_lost
        self._closed = False
        self._lock = threading.Lock()
        outer = self

        class _Listener(can.Listener):
            def on_message_received(self, msg: can.Message) -> None:
                outer._received(msg)

            def on_error(self, exc: Exception) -> None:
                outer._failed(exc)

        self._notifier = can.Notifier(bus, [_Listener()], timeout=0.05, loop=loop)

    @classmethod
    async def connect(cls, ep: Endpoint, on_data: OnData, on_lost: OnLost, timeout: float) -> CanTransport:
        loop = asyncio.get_running_loop()
        bus = await asyncio.wait_for(loop.run_in_executor(None, open_bus, ep), timeout)
        return cls(ep, bus, on_data, on_lost, loop)

    def _received(self, msg: Any) -> None:
        if self._closed:
            return
        if accepts(msg, self.ep):
            self._on_data(memoryview(msg.data))
        else:
            self.foreign += 1

    def _failed(self, exc: Exception) -> None:
        if not self._closed:
            self.close()
            self._on_lost(ConnectionResetError(f"CAN receive on {self.ep.path!r} failed: {exc}"))

    def write(self, data: bytes) -> None:
        try:
            _send(self.bus, self.ep, data, 1.0)
        except ConnectionResetError as exc:
            self._failed(exc)

    def close(self) -> None:
        with self._lock:
            if self._closed:
                return
            self._closed = True
        try:
            self._notifier.stop(0.2)
        except Exception:
            pass
        try:
            self.bus.shutdown()
        except Exception:
            pass
