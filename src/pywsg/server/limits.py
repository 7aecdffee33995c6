"""Bounds every transport keeps, so no client can make the server grow without limit."""

from __future__ import annotations

from dataclasses import dataclass

from ..protocol import CATALOG


@dataclass(frozen=True)
class Limits:
    """Per-connection and per-server bounds (bytes, seconds, counts)."""

    output_soft: int = 16 * 1024
    """Write buffer (bytes) above which auto-update packets to that client are dropped.
    Replies to requests and final replies of motions are never dropped."""
    output_hard: int = 1024 * 1024
    """Write buffer (bytes) above which the connection is closed (a client sending requests it never reads)."""
    high_water: int = 64 * 1024
    """Write buffer (bytes) at which reading from that client pauses until it drains."""
    max_connections: int = 16
    """TCP connections held open per server; more are closed at once."""
    modbus_connections: int = 32
    """Modbus/TCP masters connected at a time per gripper; more are refused (a PLC needs one or two)."""
    web_connections: int = 64
    """HTTP and WebSocket connections open at a time per web interface; more are refused."""
    keepalive_idle: int = 5
    """TCP keepalive: seconds idle before the first probe, then 1 s apart, 3 probes (half-open
    connections of a vanished client are closed after ~8 s)."""
    idle_timeout: float = 60.0
    """A Modbus/TCP or web connection with no data either way for this many seconds is closed (0:
    never), so silent peers cannot hold the connection caps."""
    denied_idle: float = 60.0
    """A connection refused control (second TCP client) is closed after this many seconds without data."""
    socket_sndbuf: int | None = None
    """SO_SNDBUF for accepted sockets (tests make it small); None keeps the kernel's."""


DEFAULT_LIMITS = Limits()

AUTO_UPDATE_IDS = frozenset(cid for cid, spec in CATALOG.items() if spec.auto_update)
"""IDs whose deferred frames are auto-update packets, the only frames a slow client may lose."""


def droppable(command_id: int) -> bool:
    """True if a deferred frame with this ID is an auto-update packet."""
    return command_id in AUTO_UPDATE_IDS
