"""Frames: ``AA AA AA | ID | SIZE (u16 LE) | PAYLOAD | CRC (u16 LE)`` (command manual 1.2.1)."""

from __future__ import annotations

import functools
import struct
from dataclasses import dataclass

from .crc import crc16
from .status import Status

PREAMBLE = b"\xaa\xaa\xaa"
HEADER_SIZE = 6  # preamble, ID, SIZE
OVERHEAD = HEADER_SIZE + 2  # ... plus the checksum
MAX_PAYLOAD = 1024  # the parser's hard cap on SIZE: 4x the largest payload (Loop, 256 bytes, 000 §3.1.1)
_HEADER = struct.Struct("<3sBH")
_STATUS = struct.Struct("<H")


def _encode(command_id: int, payload: bytes) -> bytes:
    if not 0 <= command_id <= 0xFF:
        raise ValueError(f"command ID {command_id} is not a byte")
    if len(payload) > 0xFFFF:
        raise ValueError(f"payload of {len(payload)} bytes does not fit the 16-bit SIZE field")
    body = _HEADER.pack(PREAMBLE, command_id, len(payload)) + payload
    return body + struct.pack("<H", crc16(body))


# Replies repeat (a state read answers the same bytes until the state changes): short frames are
# encoded once. Bounded, so streams of changing values cannot grow it.
_encode_cached = functools.lru_cache(maxsize=4096)(_encode)
_CACHED_PAYLOAD = 32


def encode_frame(command_id: int, payload: bytes = b"") -> bytes:
    """Whole frame bytes for ``command_id`` and ``payload``, checksum included."""
    if len(payload) <= _CACHED_PAYLOAD and type(payload) is bytes:
        return _encode_cached(command_id, payload)
    return _encode(command_id, bytes(payload))


@dataclass(frozen=True, slots=True)
class Frame:
    """One protocol frame. For replies the payload starts with the 2-byte status."""

    command_id: int
    payload: bytes = b""

    def encode(self) -> bytes:
        """The bytes on the wire."""
        return encode_frame(self.command_id, self.payload)

    @classmethod
    def reply(cls, command_id: int, status: Status | int, params: bytes = b"") -> Frame:
        """A reply frame: status code, then (for E_SUCCESS) the command's parameters."""
        return cls(command_id, _STATUS.pack(int(status)) + params)

    @property
    def status(self) -> Status | int:
        """The reply status (first two payload bytes). Raises ValueError on a 0/1-byte payload."""
        if len(self.payload) < 2:
            raise ValueError("payload too short to hold a status code")
        code: int = _STATUS.unpack_from(self.payload)[0]
        try:
            return Status(code)
        except ValueError:
            return code

    @property
    def params(self) -> bytes:
        """Reply parameters after the status code."""
        return self.payload[2:]

    def hex(self) -> str:
        """Wire bytes as ``AA AA AA 20 ...``."""
        return self.encode().hex(" ").upper()
