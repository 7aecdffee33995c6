"""Command log lines for ``wsg sim -v``: one per answered command, named from the catalog."""

from __future__ import annotations

import logging
from collections.abc import Iterable

from ..protocol import Frame, Status, command_name


def log_replies(log: logging.Logger, where: str, replies: Iterable[Frame]) -> None:
    """``tcp 127.0.0.1:5555: GET_OPENING_WIDTH (43h) -> E_SUCCESS`` at INFO (caller checks the level)."""
    for frame in replies:
        try:
            status = frame.status
            name = status.name if isinstance(status, Status) else str(status)
        except ValueError:
            name = "?"
        log.info("%s: %s (%02Xh) -> %s", where, command_name(frame.command_id), frame.command_id, name)
