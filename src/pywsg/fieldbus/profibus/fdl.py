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

A receiver frames telegrams by the line's idle time (IEC 61158-4-3): a telegram starts only after the
synchronisation time T_SYN (33 bit times of idle line), and a telegram cut off by an idle line is
dropped. The parser is told, with each chunk, whether the line was idle before it (the caller judges
that from the time gap between reads: :mod:`.line`). Within a synchronised stream it checks the start
delimiter, the length bytes, the end delimiter and the FCS; at the first error it drops everything
until the line goes idle again, so a telegram inside a damaged one (a corrupted length byte) is never
taken for a request. Tokens (SD4) and short acknowledges (SC) of other stations keep the receiver in
step and are not reported. Nothing a length byte claims is allocated: a telegram is at most 255 bytes,
so the buffer never holds more than that plus one read.
"""

from __future__ import annotations

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
REQ_IDENT = 0x0E         # Request Ident with reply
REQ_LSAP_STATUS = 0x0F   # Request LSAP Status with reply

# Response functions (FC_REQUEST clear; station type bits 4..5 = 00: slave).
RES_OK = 0x00            # positive acknowledge (FDL status reply of a slave)
RES_UE = 0x01            # user error
RES_RR = 0x02            # no resource
RES_RS = 0x03            # no service activated (SAP not active)
RES_DL = 0x08            # response data, low priority
RES_NR = 0x09            # no response data
RES_DH = 0x0A            # response data, high priority (the slave has a new diagnosis)

#: Telegram length by start delimiter, where it is fixed (SD2's is in its header).
_FIXED = {SD1: 6, SD3: 14, SD4: 3, SC: 1}

#: Synchronisation time T_SYN: idle bit times before a telegram may start (IEC 61158-4-3).
TSYN_BITS = 33
#: Bits of one UART character on the line: start, 8 data, even parity, stop.
CHAR_BITS = 11


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
    """Feed chunks from the line; get telegrams (SD1/SD2/SD3) and :class:`LineError` events.

    ``feed(data, idle=True)`` says the line was idle (at least T_SYN) before ``data``: a telegram
    begun earlier is dropped as cut off, and the receiver is in step again. ``idle=False``: ``data``
    continues the previous chunk. After an error every byte is dropped (counted in :attr:`dropped`)
    until the next idle line. Tokens (SD4) and short acknowledges (SC) of other stations are passed
    over: a slave acts on neither.
    """

    def __init__(self) -> None:
        self._buf = bytearray()
        self._in_step = True
        self.telegrams = 0
        self.errors = 0
        self.dropped = 0        # bytes dropped while out of step (after an error, before an idle line)

    @property
    def pending(self) -> int:
        """Bytes of a telegram begun but not complete."""
        return len(self._buf)

    @property
    def in_step(self) -> bool:
        """False from an error until the line goes idle."""
        return self._in_step

    def reset(self) -> None:
        """Forget a telegram begun (the caller changed the line, e.g. its baud rate)."""
        self._buf.clear()
        self._in_step = True

    def feed(self, data: bytes, *, idle: bool = False) -> list[Event]:
        out: list[Event] = []
        if idle:
            if self._buf:
                out.append(self._error("cut off by an idle line", len(self._buf)))
                self._buf.clear()
            self._in_step = True
        if not self._in_step:
            self.dropped += len(data)
            return out
        buf = self._buf
        buf += data
        i = 0
        n = len(buf)
        while i < n:
            sd = buf[i]
            size = _FIXED.get(sd)
            if size is None:
                if sd != SD2:
                    return self._lose(out, i, "no start delimiter")
                if n - i < 4:
                    break
                le = buf[i + 1]
                if buf[i + 2] != le or buf[i + 3] != SD2 or not 4 <= le <= MAX_LE:
                    return self._lose(out, i, "bad SD2 header")
                size = le + 6
            if n - i < size:
                break
            end = i + size
            if sd in (SD4, SC):         # another station's token or acknowledge
                i = end
                continue
            if buf[end - 1] != ED:
                return self._lose(out, i, "bad end delimiter")
            body_start = i + 4 if sd == SD2 else i + 1
            if fcs(memoryview(buf)[body_start:end - 2]) != buf[end - 2]:
                return self._lose(out, i, "bad FCS")
            tel = _telegram(sd, bytes(buf[body_start:end - 2]))
            if tel is None:
                return self._lose(out, i, "bad address extension")
            self.telegrams += 1
            out.append(tel)
            i = end
        del buf[:i]
        return out

    def _error(self, reason: str, skipped: int) -> LineError:
        self.errors += 1
        return LineError(reason, skipped)

    def _lose(self, out: list[Event], i: int, reason: str) -> list[Event]:
        """An error at ``i``: the rest is dropped, and so is all that follows until an idle line."""
        out.append(self._error(reason, len(self._buf) - i))
        self._buf.clear()
        self._in_step = False
        return out


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
