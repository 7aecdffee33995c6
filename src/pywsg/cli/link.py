"""A raw frame link for the Custom Command Editor and the session log: bytes in, frames out.

``wsg send`` must put the user's bytes on the wire exactly as composed (even payloads the driver
would refuse), so it talks through this thin blocking link rather than the typed driver. Every
frame sent and received goes to the :class:`~pywsg.capture.commlog.CommLog` when one is given.
Over TCP the link announces its disconnect (07h) before closing, so leaving does not raise a
FAST STOP on the gripper (command manual 1.4.2, 3.1.2). Over CAN it uses the driver's CAN transport
(:mod:`pywsg.client.can`, the same fragmenting and acceptance filter).
"""

from __future__ import annotations

import contextlib
import time
from collections import deque
from types import TracebackType

from ..capture.commlog import CommLog
from ..client import Endpoint, SyncTransport, open_transport, parse_url
from ..protocol import Command, Frame, FrameParser, Status
from ..protocol.parser import ChecksumMismatch, Event, ParseError, parse_datagram

__all__ = ["Link", "LinkError"]


class LinkError(OSError):
    """The link could not be opened or broke."""


class Link:
    """Blocking link to a gripper at ``url`` (tcp://, udp://, serial://, can://)."""

    def __init__(self, url: str, log: CommLog | None = None, connect_timeout: float = 3.0) -> None:
        self.endpoint: Endpoint = parse_url(url)
        self.log = log
        self._parser = FrameParser(verify_checksum=True)
        self._queue: deque[Event] = deque()
        try:
            self._t: SyncTransport | None = open_transport(self.endpoint, connect_timeout)
        except OSError as exc:
            why = exc.strerror or str(exc)
            if not why.startswith("cannot open"):  # the serial transport's own message names the port
                why = f"cannot open {self.endpoint}: {why}"
            raise LinkError(exc.errno or 0, why) from None

    # -- sending ---------------------------------------------------------------------------------
    def send_frame(self, frame: Frame) -> bytes:
        return self.send_raw(frame.encode(), frame)

    def send_raw(self, wire: bytes, frame: Frame | None = None) -> bytes:
        """Send ``wire`` unchanged (``frame``: its decoded form, for the log)."""
        if self.log is not None and frame is not None:
            self.log.record("tx", frame)
        try:
            self._transport().send(wire)
        except OSError as exc:
            raise LinkError(exc.errno or 0, f"send to {self.endpoint} failed: {exc}") from None
        return wire

    # -- receiving -------------------------------------------------------------------------------
    def _transport(self) -> SyncTransport:
        if self._t is None:
            raise LinkError(0, f"the link to {self.endpoint} is closed")
        return self._t

    def _read(self, timeout: float) -> list[Event]:
        t = self._transport()
        try:
            data = t.recv(timeout)
        except ConnectionResetError:
            raise LinkError(0, f"{self.endpoint} closed the connection") from None
        except OSError as exc:
            raise LinkError(exc.errno or 0, f"receive from {self.endpoint} failed: {exc}") from None
        if not data:
            return []
        return parse_datagram(data) if t.datagram else self._parser.feed(data)

    def next_event(self, timeout: float) -> Frame | ParseError | None:
        """The next received frame or parse problem, or None after ``timeout`` seconds."""
        deadline = time.monotonic() + timeout
        while not self._queue:
            left = deadline - time.monotonic()
            if left <= 0:
                return None
            for ev in self._read(left):
                if isinstance(ev, Frame) and self.log is not None:
                    self.log.record("rx", ev)
                self._queue.append(ev)
        return self._queue.popleft()

    def next_frame(self, timeout: float) -> Frame | None:
        """Like :meth:`next_event` but skipping parse problems (a checksum error raises)."""
        deadline = time.monotonic() + timeout
        while True:
            ev = self.next_event(max(0.0, deadline - time.monotonic()))
            if ev is None or isinstance(ev, Frame):
                return ev
            if isinstance(ev, ChecksumMismatch):
                raise LinkError(0, f"reply with a bad checksum: {ev.message}")

    # -- closing ---------------------------------------------------------------------------------
    def close(self, announce: bool = True) -> None:
        """Close; over TCP announce the disconnect first (07h) so the gripper keeps calm."""
        try:
            if announce and self.endpoint.scheme == "tcp" and self._t is not None:
                with contextlib.suppress(OSError):
                    self.send_frame(Frame(Command.DISCONNECT))
                    deadline = time.monotonic() + 1.0
                    while (left := deadline - time.monotonic()) > 0:
                        f = self.next_frame(left)
                        if f is None or (f.command_id == Command.DISCONNECT and f.status != Status.E_CMD_PENDING):
                            break
        finally:
            if self._t is not None:
                self._t.close()
                self._t = None

    def __enter__(self) -> Link:
        return self

    def __exit__(self, t: type[BaseException] | None, e: BaseException | None, tb: TracebackType | None) -> None:
        self.close()
