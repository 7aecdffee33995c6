"""The virtual gripper's web interface: ``serve_web(gripper, host, port)`` (see docs/web.md)."""

from __future__ import annotations

from .app import WebHandle, create_app, serve_web

__all__ = ["WebHandle", "create_app", "serve_web"]
