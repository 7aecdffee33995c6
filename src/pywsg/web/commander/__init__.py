"""The WSG Commander (000 §2) in the browser: ``wsg commander`` (see docs/commander.md).

- ``commands`` the predefined commands with their parameters in the manual's units
- ``session``  the one gripper connection through the driver: log, live state, results
- ``export``   the Communication Log as JSON lines and pcapng
- ``app``      the page, its API and WebSocket behind the web interface's guard; ``serve_commander``
"""

from __future__ import annotations

from .app import CommanderHandle, create_commander_app, serve_commander
from .session import CommanderSession

__all__ = ["CommanderHandle", "CommanderSession", "create_commander_app", "serve_commander"]
