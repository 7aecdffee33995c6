"""Open the blocking transport an endpoint names (TCP, UDP, serial, CAN). Above both the plain
transports and the CAN transport, so neither imports the other."""

from __future__ import annotations

from ..url import Endpoint
from .transport import SerialSyncTransport, SyncTransport, TcpSyncTransport, UdpSyncTransport


def open_sync(ep: Endpoint, timeout: float) -> SyncTransport:
    """A connected blocking transport for ``ep``; ``timeout`` in s for connecting and each read."""
    if ep.scheme == "tcp":
        return TcpSyncTransport(ep, timeout)
    if ep.scheme == "udp":
        return UdpSyncTransport(ep, timeout)
    if ep.scheme == "can":
        from .can_transport import CanSyncTransport  # python-can only when asked for

        return CanSyncTransport(ep, timeout)
    return SerialSyncTransport(ep, timeout)
