"""A Modbus/TCP master on a plain socket: exactly the bytes a test names, ADUs read back by MBAP length."""

from __future__ import annotations

import socket
import struct


def adu(pdu: bytes, tid: int = 1, unit: int = 1, protocol: int = 0, length: int | None = None) -> bytes:
    """MBAP header + PDU; ``length`` overrides the MBAP length field (unit id + PDU)."""
    return struct.pack(">HHHB", tid, protocol, len(pdu) + 1 if length is None else length, unit) + pdu


def read_adus(sock: socket.socket, n: int) -> list[tuple[int, bytes]]:
    """Read ``n`` response ADUs: (transaction id, PDU). Raises TimeoutError if they do not come."""
    buf = b""
    out: list[tuple[int, bytes]] = []
    while len(out) < n:
        while len(buf) >= 6 and len(buf) >= 6 + (length := struct.unpack_from(">H", buf, 4)[0]):
            tid = struct.unpack_from(">H", buf)[0]
            out.append((tid, buf[7:6 + length]))
            buf = buf[6 + length:]
        if len(out) >= n:
            break
        chunk = sock.recv(4096)
        if not chunk:
            raise ConnectionError(f"closed after {len(out)} of {n} replies")
        buf += chunk
    return out


def exchange(port: int, data: bytes, replies: int = 1, timeout: float = 3.0) -> list[tuple[int, bytes]]:
    """Send ``data`` in one write on a fresh connection; return ``replies`` response ADUs."""
    with socket.create_connection(("127.0.0.1", port), timeout=timeout) as s:
        s.sendall(data)
        return read_adus(s, replies)


def registers(pdu: bytes) -> list[int]:
    """The register values of an FC3/FC4 response PDU."""
    assert pdu[0] in (3, 4), pdu.hex()
    return [int.from_bytes(pdu[2 + 2 * i:4 + 2 * i], "big") for i in range(pdu[1] // 2)]
