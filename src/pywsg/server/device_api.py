"""The part of :class:`pywsg.device.VirtualGripper` the transports use (docs/architecture.md).

Typed as a Protocol so the transports depend on the seam, not on the model's internals.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, Protocol

from ..protocol import Frame

Deliver = Callable[[Frame], None]


class SessionLike(Protocol):
    """A device session: one per client connection (or internal user)."""


class GripperLike(Protocol):
    """What a transport needs from a virtual gripper."""

    def open_session(self, kind: str, peer: str = ..., deliver: Deliver | None = ...) -> Any: ...

    def close_session(self, session: Any) -> None: ...

    def feed(self, session: Any, data: bytes) -> list[Frame]: ...

    def handle_frame(self, session: Any, frame: Frame) -> list[Frame]: ...

    def handle_datagram(self, session: Any, data: bytes) -> list[Frame]: ...

    def poll(self) -> Any: ...

    def next_due(self) -> float | None: ...

    def add_wakeup_listener(self, fn: Callable[[], None]) -> None: ...
