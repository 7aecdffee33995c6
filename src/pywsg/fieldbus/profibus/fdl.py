"""PROFIBUS FDL (layer 2) telegrams, sans-IO: encode, and an incremental parser for a byte stream.

Telegram formats (IEC 61158-4-3 / EN 50170, the "Fieldbus Data Link"):

======  =====================================================  ===========================
SD1     ``10 DA SA FC FCS 16``                                 no data unit
SD2     ``68 LE LEr 68 DA SA FC [DAE] [SAE] DU… FCS 16``        variable data unit, LE 4…249
SD3     ``A2 DA SA FC DU(8) FCS 16``                           fixed 8-byte data unit
SD4     ``DC DA SA``                                           token (masters only: ignored)
SC      ``E5``                                                 short acknowledge
======  =====================================================  ===========================

FCS is the arithmetic sum modulo 256 of DA, SA, FC and the data unit. Bit 7 of DA (SA) says that a
destination (source) address extension byte leads the data unit: its low 6 bits are the service access
point (SAP), bit 6 marks a segment address, bit 7 another extension byte.

A real RS-485 receiver frames telegrams by idle time on the line; a pty has none, so the parser frames
by structure: it checks the start delimiter, the length bytes, the end delimiter and the FCS, and after
an error resumes at the next byte that can start a telegram (one regex search, so 1 MiB of garbage
costs one pass). A structurally sound SD2 whose FCS fails is skipped whole. Nothing a length byte
claims is allocated: a telegram is at most 255 bytes, so the buffer never holds more than that plus
one read.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

SD1 = 0x10
SD2 = 0x68
SD3 = 0xA2
SD4 = 0xDC
SC = 0xE5
ED = 0x16

#: The short acknowledge, whole.
SHORT_ACK = bytes([SC])

BROADCAST = 127          # DA of a broadcast (Global_Control)
ADDRESS_EXT = 0x80       # DA/SA bit 7: an address extension byte follows in the data unit
AE_MORE = 0x80           # in an extension byte: another extension byte follows
AE_SEGMENT = 0x40        # in an extension byte: a segment address, not a SAP
MAX_LE = 249             # SD2: LE counts DA, SA, FC and the data unit
MAX_TELEGRAM = MAX_LE + 6

# Frame control (FC) byte.
FC_REQUEST = 0x40
FC_FCB = 0x20            # request: frame count bit
FC_FCV = 0x10            # request: frame count bit valid
FC_FUNCTION = 0x0F

# Request functions (FC_REQUEST set).
REQ_SDA_LO = 0x03
REQ_SDN_LO = 0x04
REQ_SDA_HI = 0x05
REQ_SDN_HI = 0x06
REQ_FDL_STATUS = 0x09
REQ_SRD_LO = 0x0C
REQ_SRD_HI = 0x0D
REQ_IDENT = 0x0E

# Response functions (FC_REQUEST clear; station type bits 4..5 = 00: slave).
RES_OK = 0x00            # positive acknowledge (FDL status reply of a slave)
RES_UE = 0x01            # user error
RES_RR = 0x02            # no resource
RES_RS = 0x03            # no service activated (SAP not active)
RES_DL = 0x08            # response data, low priority
RES_NR = 0x09            # no response data
RES_DH = 0x0A            # response data, high priority (the slave has a new diagnosis)

# A slave resynchronises only on the delimiters of telegrams it may have to answer: a token (SD4) or a
# short acknowledge (SC) on the line is someone else's business, and skipping them with the garbage
# keeps the cost of a stream of E5 bytes as low as that of any other noise.
_START = re.compile(rb"[\x10\x68\xa2]")
# Where a telegram can start: its delimiters at the right distance (SD1, SD3) or an SD2 header with two
# equal, valid length bytes. Searching for this in C skips any noise without a Python step per byte.
_PLAUSIBLE = re.compile(rb"\x10[\x00-\xff]{4}\x16|\xa2[\x00-\xff]{12}\x16|\x68([\x04-\xf9])\1\x68", re.DOTALL)
_LONGEST_FIXED = 14
_FIXED = {SD1: 6, SD3: 14}


def fcs(data: bytes | bytearray | memoryview) -> int:
    """The frame check sequence: sum of the bytes modulo 256."""
    return sum(data) & 0xFF


@dataclass(frozen=True)
class Telegram:
    """One FDL telegram. ``da``/``sa`` are the 7-bit addresses; ``dsap``/``ssap`` the service access
    points from the address extensions (None: none, the "default SAP" of Data_Exchange); ``data`` is
    the data unit without the extension bytes."""

    da: int
    sa: int
    fc: int
    data: bytes = b""
    dsap: int | None = None
    ssap: int | None = None
    sd: int = field(default=0, compare=False)

    @property
    def is_request(self) -> bool:
        return bool(self.fc & FC_REQUEST)

    @property
    def function(self) -> int:
        return self.fc & FC_FUNCTION

    def encode(self) -> bytes:
        """The telegram's bytes: SD1 without data unit, SD3 for exactly 8 bytes, else SD2."""
        return encode(self.da, self.sa, self.fc, self.data, self.dsap, self.ssap)


def encode(da: int, sa: int, fc: int, data: bytes = b"", dsap: int | None = None, ssap: int | None = None) -> bytes:
    """Encode one telegram (see :class:`Telegram`)."""
    if not (0 <= da <= 127 and 0 <= sa <= 127):
        raise ValueError("FDL addresses are 0..127")
    head = bytearray()
    if dsap is not None:
        da |= ADDRESS_EXT
        head.append(dsap & 0x3F)
    if ssap is not None:
        sa |= ADDRESS_EXT
        head.append(ssap & 0x3F)
    du = bytes(head) + data
    body = bytes((da, sa, fc)) + du
    if not du:
        return bytes((SD1, *body, fcs(body), ED))
    if len(du) == 8:
        return bytes((SD3, *body, fcs(body), ED))
    le = len(body)
    if le > MAX_LE:
        raise ValueError(f"data unit too long ({len(du)} bytes, at most {MAX_LE - 3})")
    return bytes((SD2, le, le, SD2, *body, fcs(body), ED))


@dataclass(frozen=True)
class LineError:
    """Bytes the parser dropped, and why (bad FCS, bad end delimiter, bad length, no start delimiter)."""

    reason: str
    skipped: int


Event = Telegram | LineError


class FdlParser:
    """Feed bytes from the line; get telegrams (SD1/SD2/SD3) and :class:`LineError` events.

    Tokens (SD4) and short acknowledges (SC) of other stations are skipped like noise: a slave acts on
    neither.
    """

    def __init__(self) -> None:
        self._buf = bytearray()
        self.telegrams = 0
        self.errors = 0

    @property
    def pending(self) -> int:
        """Bytes of a telegram begun but not complete."""
        return len(self._buf)

    def reset(self) -> None:
        self._buf.clear()

    def feed(self, data: bytes) -> list[Event]:
        buf = self._buf
        buf += data
        out: list[Event] = []
        i = 0
        n = len(buf)
        while i < n:
            sd = buf[i]
            size = _FIXED.get(sd)
            if size is None and sd != SD2:
                i = self._resync(out, i - 1, "no start delimiter")
                continue
            if sd == SD2:
                if n - i < 4:
                    break
                le = buf[i + 1]
                if buf[i + 2] != le or buf[i + 3] != SD2 or not 4 <= le <= MAX_LE:
                    i = self._resync(out, i, "bad SD2 header")
                    continue
                size = le + 6
            assert size is not None
            if n - i < size:
                break
            end = i + size
            if buf[end - 1] != ED:
                if sd == SD2:    # four header bytes agreed: the receiver counted the telegram off whole
                    out.append(self._error("bad end delimiter", size))
                    i = end
                else:
                    i = self._resync(out, i, "bad end delimiter")
                continue
            body_start = i + 4 if sd == SD2 else i + 1
            if fcs(memoryview(buf)[body_start:end - 2]) != buf[end - 2]:
                if sd == SD2:    # the header held: skip the whole telegram
                    out.append(self._error("bad FCS", size))
                    i = end
                else:
                    i = self._resync(out, i, "bad FCS")
                continue
            tel = _telegram(sd, bytes(buf[body_start:end - 2]))
            if tel is None:
                out.append(self._error("bad address extension", size))
            else:
                self.telegrams += 1
                out.append(tel)
            i = end
        del buf[:i]
        return out

    def _error(self, reason: str, skipped: int) -> LineError:
        self.errors += 1
        return LineError(reason, skipped)

    def _resync(self, out: list[Event], i: int, reason: str) -> int:
        """Drop from ``i + 1`` to where a telegram can start; a tail too short to tell is kept."""
        buf = self._buf
        m = _PLAUSIBLE.search(buf, i + 1)
        if m is not None:
            j = m.start()
        else:
            tail = _START.search(buf, max(i + 1, len(buf) - _LONGEST_FIXED))
            j = tail.start() if tail else len(buf)
        out.append(self._error(reason, j - i))
        return j


def _telegram(sd: int, body: bytes) -> Telegram | None:
    """DA SA FC DU → Telegram, with the address extensions taken off the data unit (None: cut short)."""
    da, sa, fc = body[0], body[1], body[2]
    du = body[3:]
    dsap = ssap = None
    if da & ADDRESS_EXT:
        ext = _extension(du)
        if ext is None:
            return None
        dsap, du = ext
    if sa & ADDRESS_EXT:
        ext = _extension(du)
        if ext is None:
            return None
        ssap, du = ext
    return Telegram(da & 0x7F, sa & 0x7F, fc, bytes(du), dsap, ssap, sd)


def _extension(du: bytes) -> tuple[int | None, bytes] | None:
    """(SAP or None, rest) from the extension bytes leading ``du``; None when they are cut short."""
    sap: int | None = None
    for k, b in enumerate(du):
        if not b & AE_SEGMENT and sap is None:
            sap = b & 0x3F
        if not b & AE_MORE:
            return sap, du[k + 1:]
    return None
