"""Client sessions: one per connection (or internal user such as the fieldbus or the web UI)."""

from __future__ import annotations

import itertools
from collections.abc import Callable
from dataclasses import dataclass, field

from ..protocol import Frame, FrameParser

Deliver = Callable[[Frame], None]

_ids = itertools.count(1)


@dataclass(slots=True)
class Subscription:
    """An auto-update request (40h, 41h, 43h, 44h, 45h with FLAGS D0 set).

    ``period`` in seconds; ``change_only`` sends only when the value moved by the manual's
    threshold (and still keeps ``period`` between packets).
    """

    command_id: int
    period: float
    change_only: bool
    next_time: float
    last_value: float | int | None = None
    checked_version: int = -1


@dataclass(eq=False)
class Session:
    """State the device keeps per client: parser, auto-update subscriptions, disconnect rules.

    ``kind``: ``tcp``, ``udp``, ``serial``, ``can``, ``fieldbus``, ``web``, ... Only ``tcp`` is
    connection oriented (07h allowed, FAST STOP on an unannounced close).
    """

    kind: str
    peer: str = ""
    deliver: Deliver | None = None
    id: int = field(default_factory=lambda: next(_ids))
    parser: FrameParser = field(default_factory=FrameParser)
    subscriptions: dict[int, Subscription] = field(default_factory=dict)
    announced: bool = False  # 07h received: every further command gets E_ACCESS_DENIED
    denied: bool = False  # a second TCP client while another holds the command interface
    closed: bool = False

    @property
    def connection_oriented(self) -> bool:
        return self.kind == "tcp"

    def __repr__(self) -> str:
        return f"Session({self.kind!r}, peer={self.peer!r}, id={self.id})"
