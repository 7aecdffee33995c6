"""DCE/RPC connectionless (v4) for PROFINET IO, sans-IO: the 80-byte header and the NDR wrapper.

Multi-byte header fields and the first three UUID fields follow the sender's data representation
(DREP byte 0: 10h little endian, 00h big endian); the PNIO blocks inside are always big endian.
The device answers little endian (DREP 10h), whatever the request used, as IO devices commonly do
(controllers such as profinet-py read the NDR status that way). Fragmented requests are refused (a connect of the
WSG's two slots fits one datagram).
"""

from __future__ import annotations

import struct
import uuid
from dataclasses import dataclass, replace

RPC_PORT = 34964
HEADER_LEN = 80
NDR_LEN = 20

REQUEST, PING, RESPONSE, FAULT, WORKING, NOCALL, REJECT, ACK = 0, 1, 2, 3, 4, 5, 6, 7
FLAG_LASTFRAG, FLAG_FRAG, FLAG_NOFACK, FLAG_IDEMPOTENT = 0x02, 0x04, 0x08, 0x20
OP_CONNECT, OP_RELEASE, OP_READ, OP_WRITE, OP_CONTROL, OP_READ_IMPLICIT = range(6)
EPM_LOOKUP = 2

UUID_DEVICE = uuid.UUID("dea00001-6c97-11d1-8271-00a02442df7d")
UUID_CONTROLLER = uuid.UUID("dea00002-6c97-11d1-8271-00a02442df7d")
UUID_EPM = uuid.UUID("e1af8308-5d1f-11c9-91a4-08002b14a0fa")
#: nca_unk_if / nca_op_rng_error: reject codes for an unknown interface or operation.
NCA_UNK_IF, NCA_OP_RNG_ERROR, NCA_PROTO_ERROR = 0x1C010003, 0x1C010002, 0x1C01000B


def object_uuid(vendor_id: int, device_id: int, instance: int = 1) -> uuid.UUID:
    """The PNIO object UUID DEA00000-6C97-11D1-8271-{instance}{device}{vendor} (IEC 61158-6-10)."""
    return uuid.UUID(f"dea00000-6c97-11d1-8271-{instance:04x}{device_id:04x}{vendor_id:04x}")


@dataclass(frozen=True)
class RpcHeader:
    ptype: int
    flags1: int
    flags2: int
    drep: bytes
    object: uuid.UUID
    interface: uuid.UUID
    activity: uuid.UUID
    boot_time: int
    if_version: int
    seqnum: int
    opnum: int
    body_len: int
    fragnum: int
    serial: int

    @property
    def little(self) -> bool:
        return bool(self.drep[0] & 0x10)


def _uuid(raw: bytes, little: bool) -> uuid.UUID:
    return uuid.UUID(bytes_le=raw) if little else uuid.UUID(bytes=raw)


def _uuid_raw(u: uuid.UUID, little: bool) -> bytes:
    return u.bytes_le if little else u.bytes


def parse(data: bytes) -> tuple[RpcHeader, bytes] | None:
    """Header and body, or None when it is not a DCE/RPC CL v4 packet or the body length lies."""
    if len(data) < HEADER_LEN or data[0] != 4:
        return None
    drep = data[4:7]
    little = bool(drep[0] & 0x10)
    bo = "<" if little else ">"
    boot, ver, seq, op, _ih, _ah, blen, frag = struct.unpack_from(bo + "IIIHHHHH", data, 56)
    if blen > len(data) - HEADER_LEN:
        return None
    hdr = RpcHeader(data[1], data[2], data[3], drep, _uuid(data[8:24], little), _uuid(data[24:40], little),
                    _uuid(data[40:56], little), boot, ver, seq, op, blen, frag, (data[7] << 8) | data[79])
    return hdr, data[HEADER_LEN:HEADER_LEN + blen]


def build(hdr: RpcHeader, body: bytes) -> bytes:
    little = hdr.little
    bo = "<" if little else ">"
    return (bytes([4, hdr.ptype, hdr.flags1, hdr.flags2]) + hdr.drep + bytes([hdr.serial >> 8 & 0xFF])
            + _uuid_raw(hdr.object, little) + _uuid_raw(hdr.interface, little) + _uuid_raw(hdr.activity, little)
            + struct.pack(bo + "IIIHHHHH", hdr.boot_time, hdr.if_version, hdr.seqnum, hdr.opnum, 0xFFFF, 0xFFFF,
                          len(body), hdr.fragnum)
            + bytes([0, hdr.serial & 0xFF]) + body)


LITTLE_ENDIAN = b"\x10\x00\x00"


def response(req: RpcHeader, body: bytes, boot_time: int, ptype: int = RESPONSE) -> bytes:
    """A reply to ``req``, little endian (same UUIDs, sequence and operation numbers); ``body`` must be
    encoded little endian too."""
    hdr = replace(req, drep=LITTLE_ENDIAN, ptype=ptype, flags1=FLAG_LASTFRAG | FLAG_NOFACK, flags2=0,
                  boot_time=boot_time, fragnum=0)
    return build(hdr, body)


def reject(req: RpcHeader, status: int, boot_time: int) -> bytes:
    return response(req, struct.pack("<I", status), boot_time, ptype=REJECT)


@dataclass(frozen=True)
class Ndr:
    """NDR array header of a PNIO request: ArgsMaximum and the arguments."""

    args_maximum: int
    args: bytes


def parse_ndr(body: bytes, little: bool) -> Ndr | None:
    if len(body) < NDR_LEN:
        return None
    bo = "<" if little else ">"
    args_max, args_len, _max_count, offset, actual = struct.unpack_from(bo + "IIIII", body)
    if offset != 0 or args_len != actual or args_len > len(body) - NDR_LEN:
        return None
    return Ndr(args_max, body[NDR_LEN:NDR_LEN + args_len])


def ndr_response(status: int, args: bytes, args_maximum: int, little: bool) -> bytes:
    """PNIOStatus (ErrorCode, ErrorDecode, ErrorCode1, ErrorCode2 as one 32-bit number in the
    request's representation, as Wireshark reads it) + the NDR header + ``args``."""
    bo = "<" if little else ">"
    return struct.pack(bo + "IIIII", status, len(args), args_maximum, 0, len(args)) + args


def ndr_request(args: bytes, little: bool, args_maximum: int = 4096) -> bytes:
    bo = "<" if little else ">"
    return struct.pack(bo + "IIIII", max(args_maximum, len(args)), len(args), max(args_maximum, len(args)), 0,
                       len(args)) + args
