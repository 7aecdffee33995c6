"""CRC of any window of a buffer in O(1), from running CRC states (for overlapping frame candidates).

The WSG checksum (:mod:`.crc`) is affine in its input: one update step is
``crc' = g(crc) ^ T[byte]`` with ``g(c) = T[c & 0xFF] ^ (c >> 8)`` linear over GF(2). So if
``S(i)`` is the running state over ``buf[0:i]`` from *any* start value, the checksum of the window
``buf[p:e]`` from FFFFh is ``S(e) ^ g^(e-p)(S(p) ^ FFFFh)``. A parser that must test many
overlapping candidate frames (``AA AA AA`` headers every few bytes, each announcing 1 KiB) computes
each byte's state once and then checks every candidate with two table look-ups, instead of a CRC
of up to 1 KiB per candidate.

``g^n`` is applied as two 256-entry tables (low byte, high byte), built for every ``n`` up to the
longest window asked for (1 KiB frames: about 1 MB, built once per process in ~50 ms).
"""

from __future__ import annotations

import struct
from array import array
from itertools import accumulate

from .crc import _WORD_TABLE, CRC_INIT, CRC_TABLE

_SHIFT_LO: list[array[int]] = []
_SHIFT_HI: list[array[int]] = []


def _step0(c: int) -> int:
    return CRC_TABLE[c & 0xFF] ^ (c >> 8)


def _extend_shift_tables(n: int) -> None:
    """Tables of ``g^k`` for every ``k <= n`` (``g^0`` is the identity)."""
    if not _SHIFT_LO:
        _SHIFT_LO.append(array("H", range(256)))
        _SHIFT_HI.append(array("H", (i << 8 for i in range(256))))
    while len(_SHIFT_LO) <= n:
        lo, hi = _SHIFT_LO[-1], _SHIFT_HI[-1]
        _SHIFT_LO.append(array("H", [_step0(v) for v in lo]))
        _SHIFT_HI.append(array("H", [_step0(v) for v in hi]))


def shift(state: int, n: int) -> int:
    """``g^n(state)``: the state after ``n`` zero bytes, without the zero bytes' own contribution."""
    if n >= len(_SHIFT_LO):
        _extend_shift_tables(n)
    return _SHIFT_LO[n][state & 0xFF] ^ _SHIFT_HI[n][state >> 8]


def _states_after(crc: int, chunk: bytes | bytearray) -> array[int]:
    """Running states after each byte of ``chunk`` starting from ``crc`` (two bytes per table step)."""
    k = len(chunk)
    pairs = k >> 1
    evens = list(accumulate(struct.unpack_from(f"<{pairs}H", chunk), _word_step, initial=crc))
    t = CRC_TABLE
    odds = [t[(c ^ b) & 0xFF] ^ (c >> 8) for c, b in zip(evens[:pairs], chunk[0 : 2 * pairs : 2], strict=True)]
    if k & 1:
        c = evens[-1]
        odds.append(t[(c ^ chunk[k - 1]) & 0xFF] ^ (c >> 8))
    out = array("H", bytes(2 * k))
    out[0::2] = array("H", odds)
    out[1::2] = array("H", evens[1:])
    return out


def _word_step(crc: int, word: int) -> int:
    return _WORD_TABLE[crc ^ word]


class RunningCrc:
    """Running CRC states over a growing buffer, one per byte position, computed on demand.

    :meth:`window` answers the checksum of ``buf[p:e]`` from FFFFh. Positions are buffer indexes;
    :meth:`drop` follows a ``del buf[:k]`` of the owner's buffer. Memory: two bytes per position
    covered (the owner keeps at most one maximal frame plus one read).
    """

    __slots__ = ("_base", "_states")

    def __init__(self) -> None:
        self._base = 0  # buffer index of _states[0]
        self._states = array("H")

    def __len__(self) -> int:
        return len(self._states)

    def clear(self) -> None:
        del self._states[:]

    def _state(self, buf: bytes | bytearray, i: int) -> int:
        states = self._states
        if not states or i < self._base:
            # (re)anchor here: any start value works, only differences of states are used
            self._base = i
            states[:] = array("H", [0])
        need = i - self._base
        have = len(states) - 1
        if need > have:
            states.extend(_states_after(states[-1], buf[self._base + have : i]))
        return states[need]

    def window(self, buf: bytes | bytearray, p: int, e: int) -> int:
        """CRC (from FFFFh) of ``buf[p:e]``, ``p <= e``; each byte's running state is computed once."""
        states = self._states
        base = self._base
        if not states or p < base:
            self._state(buf, p)
            base = self._base
        if e - base >= len(states):
            # in steps of at least 2 KiB: one call per run of candidates, not per candidate
            self._state(buf, min(max(e, base + len(states) + 2048), len(buf)))
        sp = states[p - base] ^ CRC_INIT
        n = e - p
        if n >= len(_SHIFT_LO):
            _extend_shift_tables(n)
        return states[e - base] ^ _SHIFT_LO[n][sp & 0xFF] ^ _SHIFT_HI[n][sp >> 8]

    def drop(self, k: int) -> None:
        """The owner deleted ``buf[:k]``: renumber (states before ``k`` are forgotten)."""
        base = self._base - k
        if base < 0:
            del self._states[: min(-base, len(self._states))]
            base = 0
        self._base = base
