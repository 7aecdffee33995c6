"""Blocking CAN transport of :class:`~pywsg.client.Gripper` (``can://``; mapping in :mod:`pywsg.client.can`)."""

from __future__ import annotations

import time

from ..can import CAN_DLEN, DRAIN, accepts, open_bus, send
from ..url import Endpoint
from .transport import SyncTransport


class CanSyncTransport(SyncTransport):
    """Blocking: ``recv`` returns the bytes of the reply frames available (at least one CAN frame)."""

    def __init__(self, ep: Endpoint, timeout: float) -> None:
        self.ep = ep
        self.bus = open_bus(ep)
        self.peer = str(ep)
        self._send_timeout = timeout
        self.foreign = 0  # frames ignored (another identifier, remote, error)

    def send(self, data: bytes) -> None:
        send(self.bus, self.ep, data, self._send_timeout)

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
                    if len(out) >= DRAIN * CAN_DLEN:
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
