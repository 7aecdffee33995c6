"""The WSG checksum (command manual, Appendix D).

A table of the non-reflected CCITT polynomial 1021h driven by a reflected update,
``crc = T[(crc ^ byte) & 0xFF] ^ (crc >> 8)``, start FFFFh, no final XOR, sent low byte
first. No standard CRC model matches that mix, so it is computed here.

:func:`crc16` folds two bytes per step through a 65536-entry table derived from the
manual's table (``T2[i] == two table steps for the word i``): about 4x the per-byte loop
in pure Python.
"""

from __future__ import annotations

import struct
import sys
from array import array

CRC_INIT = 0xFFFF
PREAMBLE_CRC = 0x50F5  # the CRC after AA AA AA alone: a receiver may start from here


def _make_table() -> tuple[int, ...]:
    table = []
    for i in range(256):
        crc = i << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x1021) if crc & 0x8000 else (crc << 1)
        table.append(crc & 0xFFFF)
    return tuple(table)


CRC_TABLE: tuple[int, ...] = _make_table()


def _make_word_table() -> list[int]:
    t = CRC_TABLE
    out = [0] * 65536
    for idx in range(65536):
        first = t[idx & 0xFF]
        out[idx] = t[(first & 0xFF) ^ (idx >> 8)] ^ (first >> 8)
    return out


_WORD_TABLE: list[int] = _make_word_table()
_LITTLE = sys.byteorder == "little"


def crc16_bytewise(data: bytes | bytearray | memoryview, crc: int = CRC_INIT) -> int:
    """Appendix D's loop, one byte a step. The reference the fast version is tested against."""
    t = CRC_TABLE
    for b in bytes(data):
        crc = t[(crc ^ b) & 0xFF] ^ (crc >> 8)
    return crc


_WORD_STRUCTS: dict[int, struct.Struct] = {}
_CACHED_WORDS = 640  # struct objects cached for frames up to 1280 bytes (the parser's cap is 1 KiB)


def crc16(data: bytes | bytearray | memoryview, crc: int = CRC_INIT) -> int:
    """CRC of ``data`` continuing from ``crc`` (FFFFh for a new frame)."""
    n = len(data)
    nwords = n >> 1
    t2 = _WORD_TABLE
    if nwords:
        if nwords <= _CACHED_WORDS:
            st = _WORD_STRUCTS.get(nwords)
            if st is None:
                st = _WORD_STRUCTS.setdefault(nwords, struct.Struct(f"<{nwords}H"))
            words: tuple[int, ...] | array[int] = st.unpack_from(data)
        else:
            words = array("H")
            words.frombytes(bytes(data[: n & ~1]))
            if not _LITTLE:
                words.byteswap()
        for w in words:
            crc = t2[crc ^ w]
    if n & 1:
        crc = CRC_TABLE[(crc ^ data[n - 1]) & 0xFF] ^ (crc >> 8)
    return crc


def checksum_bytes(data: bytes | bytearray | memoryview) -> bytes:
    """The two checksum bytes (low byte first) that follow ``data`` in a frame."""
    return struct.pack("<H", crc16(data))
