"""The Custom Command Editor syntax, now in :mod:`pywsg.protocol.editor` (the web Commander reads it too)."""

from __future__ import annotations

from ..protocol.editor import (
    Item,
    Packet,
    PayloadSyntaxError,
    build_packet,
    parse_command_id,
    parse_item,
    parse_items,
    parse_payload,
    tokenize,
    tokens,
)

__all__ = [
    "Item", "Packet", "PayloadSyntaxError", "build_packet", "parse_command_id", "parse_item", "parse_items",
    "parse_payload", "tokenize", "tokens",
]
