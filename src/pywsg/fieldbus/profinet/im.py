"""Identification & Maintenance records I&M0–I&M4 and I&M0FilterData (IEC 61158-6-10, PROFINET
guideline "Identification & Maintenance Functions"), sans-IO.

The device access point (slot 0, subslot 1) carries the device's I&M data; every other submodule is
represented by it, so I&M0FilterData lists only that one and a read of I&M at any real submodule
answers with the device's data.

- I&M0 (AFF0h, read only): vendor, order ID, serial number, hardware/software revision, IM_Supported
  (bits 1–4: I&M1–I&M4 present);
- I&M1 (AFF1h): IM_Tag_Function (32 characters) and IM_Tag_Location (22), I&M2 (AFF2h): IM_Date
  ("YYYY-MM-DD HH:MM"), I&M3 (AFF3h): IM_Descriptor (54) — visible strings padded with blanks,
  written by the engineering tool and kept across restarts (``settings.interface.json``);
- I&M4 (AFF4h): IM_Signature, 54 octets the engineering tool writes (for a functional-safety
  signature) and reads back: kept like I&M1–3, all zero until written, as the guideline says.
"""

from __future__ import annotations

import re
import struct
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from . import blocks as b

if TYPE_CHECKING:
    from .station import Station

IM0, IM1, IM2, IM3, IM4, IM0_FILTER = 0xAFF0, 0xAFF1, 0xAFF2, 0xAFF3, 0xAFF4, 0xF840
BLOCK_IM0, BLOCK_IM1, BLOCK_IM2, BLOCK_IM3, BLOCK_IM4 = 0x0020, 0x0021, 0x0022, 0x0023, 0x0024
BLOCK_FILTER_SUBMODULE, BLOCK_FILTER_MODULE, BLOCK_FILTER_DEVICE = 0x0030, 0x0031, 0x0032
#: IM_Supported: I&M1, I&M2, I&M3 and I&M4 are there (bit n: I&Mn).
IM_SUPPORTED = 0b11110
#: IM_ProfileSpecificType 0004h with IM_Profile_ID 0000h: a device without an application profile.
PROFILE_SPECIFIC_TYPE = 0x0004
#: The submodule that carries the I&M data: the device access point's (slot 0, subslot 1).
IM_CARRIER = (0, 1)
WRITE_LENGTH_ERROR, INVALID_PARAMETER, INVALID_RANGE = 0xB1, 0xB8, 0xB7

#: The writable I&M records: index → (block type, field names and their lengths).
FIELDS: dict[int, tuple[int, tuple[tuple[str, int], ...]]] = {
    IM1: (BLOCK_IM1, (("im1_tag_function", 32), ("im1_tag_location", 22))),
    IM2: (BLOCK_IM2, (("im2_date", 16),)),
    IM3: (BLOCK_IM3, (("im3_descriptor", 54),)),
    IM4: (BLOCK_IM4, (("im4_signature", 54),)),
}
_DATE = re.compile(r"\d{4}-(0[1-9]|1[0-2])-(0[1-9]|[12]\d|3[01]) ([01]\d|2[0-3]):[0-5]\d")


@dataclass(frozen=True)
class Identity:
    """I&M0 values (IEC 61158-6-10 I&M0 record, AFF0h)."""

    order_id: str
    serial_number: str
    hardware_revision: int = 1
    software_revision: tuple[str, int, int, int] = ("V", 4, 0, 0)
    revision_counter: int = 0


def im0(station: Station, ident: Identity) -> bytes:
    """I&M0 (block 0020h): VendorID, OrderID (20), IM_Serial_Number (16), IM_Hardware_Revision,
    IM_Software_Revision (V x.y.z), IM_Revision_Counter, IM_Profile_ID, IM_Profile_Specific_Type,
    IM_Version 1.1, IM_Supported."""
    sw = ident.software_revision
    body = (struct.pack("!H", station.vendor_id) + ident.order_id.encode("ascii")[:20].ljust(20)
            + ident.serial_number.encode("ascii")[:16].ljust(16)
            + struct.pack("!H", ident.hardware_revision) + sw[0].encode("ascii")[:1] + bytes(sw[1:])
            + struct.pack("!HHHBBH", ident.revision_counter, 0, PROFILE_SPECIFIC_TYPE, 1, 1, IM_SUPPORTED))
    return b.header(BLOCK_IM0, body)


def im0_filter(dap_module: int, dap_submodule: int) -> bytes:
    """I&M0FilterData (F840h): the submodules that carry I&M0 (0030h), those that stand for their module
    (0031h) and the one that stands for the device (0032h) — each time the device access point's; the
    other submodules have no I&M data of their own."""
    body = struct.pack("!HIHHIHHI", 1, 0, 1, IM_CARRIER[0], dap_module, 1, IM_CARRIER[1], dap_submodule)
    return b"".join(b.header(kind, body) for kind in (BLOCK_FILTER_SUBMODULE, BLOCK_FILTER_MODULE,
                                                       BLOCK_FILTER_DEVICE))


def _visible(raw: bytes) -> bool:
    return all(0x20 <= c <= 0x7E for c in raw)


@dataclass
class IMData:
    """I&M1–4 values (strings padded with blanks; ``im4_signature`` as bytes) and who stores them."""

    values: dict[str, Any] = field(default_factory=dict)
    #: Called with the changed keys after a write, e.g. to put them into the settings file.
    save: Callable[[dict[str, Any]], None] | None = None

    def __post_init__(self) -> None:
        for _index, (_block, fields) in FIELDS.items():
            for key, size in fields:
                value = self.values.get(key)
                if key == "im4_signature":
                    raw = bytes.fromhex(value) if isinstance(value, str) and _hex(value, size) else bytes(size)
                    self.values[key] = raw
                else:
                    text = value if isinstance(value, str) and len(value) <= size and _visible(value.encode(
                        "ascii", errors="replace")) else ""
                    self.values[key] = text.ljust(size)

    @classmethod
    def load(cls, stored: Mapping[str, Any], save: Callable[[dict[str, Any]], None] | None = None) -> IMData:
        """The values a settings file holds (its other keys ignored; a bad value reads as blank)."""
        keys = {k for _b, fields in FIELDS.values() for k, _n in fields}
        return cls({k: v for k, v in stored.items() if k in keys}, save)

    def field_bytes(self, key: str) -> bytes:
        value = self.values[key]
        return value if isinstance(value, bytes) else str(value).encode("ascii")

    def record(self, index: int) -> bytes:
        block, fields = FIELDS[index]
        return b.header(block, b"".join(self.field_bytes(k) for k, _ in fields))

    def write(self, index: int, data: bytes) -> int:
        """Apply a write of I&M1–4 (the whole block, header included); 0 or the PNIORW ErrorCode1."""
        block, fields = FIELDS[index]
        size = sum(n for _, n in fields)
        if len(data) != 6 + size:
            return WRITE_LENGTH_ERROR
        btype, blen, vhigh, _vlow = struct.unpack_from("!HHBB", data)
        if btype != block or blen != size + 2 or vhigh != 1:
            return INVALID_PARAMETER
        new: dict[str, Any] = {}
        off = 6
        for key, n in fields:
            raw = data[off:off + n]
            off += n
            if key == "im4_signature":
                new[key] = raw
                continue
            if not _visible(raw):
                return INVALID_PARAMETER
            text = raw.decode("ascii")
            if key == "im2_date" and text.strip() and not _DATE.fullmatch(text):
                return INVALID_RANGE
            new[key] = text
        self.values.update(new)
        if self.save is not None:
            self.save({k: v.hex() if isinstance(v, bytes) else v.rstrip() for k, v in new.items()})
        return 0


def _hex(text: str, size: int) -> bool:
    try:
        return len(bytes.fromhex(text)) == size
    except ValueError:
        return False


class IMRecords:
    """The I&M records as a record handler of :class:`~pywsg.fieldbus.profinet.ar.ConnectionManager`."""

    def __init__(self, station: Station, identity: Identity, data: IMData | None = None, *,
                 dap_module: int = 1, dap_submodule: int = 1) -> None:
        self.station = station
        self.identity = identity
        self.data = data or IMData()
        self.dap = (dap_module, dap_submodule)

    def read(self, req: b.RecordRequest, ar: object, real: bool) -> bytes | None:
        """The record, or None when it is not an I&M record (``real``: the address is a real submodule)."""
        if req.index == IM0_FILTER:
            return im0_filter(*self.dap)
        if not real:
            return None
        if req.index == IM0:
            return im0(self.station, self.identity)
        if req.index in FIELDS:
            return self.data.record(req.index)
        return None

    def write(self, req: b.RecordRequest, ar: object, data: bytes) -> int | None:
        """0, a PNIORW ErrorCode1, or None when the index is not an I&M record."""
        if req.index in FIELDS:
            return self.data.write(req.index, data)
        if req.index in (IM0, IM0_FILTER):
            return 0xB6   # access denied: read-only records
        return None
