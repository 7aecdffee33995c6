"""Modbus/TCP conformance on raw sockets: exactly these bytes, these answers.

Modbus Application Protocol Specification V1.1b3 (§6.x quantity ranges, §7 exception codes, FC5
§6.5 "values other than 0xFF00 and 0x0000 are illegal") and the Modbus Messaging on TCP/IP
Implementation Guide V1.0b (§3.1.3 MBAP header; a TCP stream carries any number of ADUs). pymodbus
3.16 gets several of these wrong on its own; docs/fieldbus.md ("Conformance") says what pywsg does.
"""

from __future__ import annotations

import asyncio
import socket
from collections.abc import AsyncIterator

import pytest
from hypothesis import given
from hypothesis import strategies as st

from pywsg.fieldbus.modbus.server import check_pdu
from pywsg.server import SimServer

from .raw_modbus import adu, exchange, read_adus, registers

pytestmark = [pytest.mark.realtime, pytest.mark.pymodbus]  # pymodbus: also run on the oldest pin (scripts/test.sh)


@pytest.fixture
async def port() -> AsyncIterator[int]:
    async with SimServer(tcp_port=None, udp_port=None, modbus_port=0) as s:
        yield s.modbus_port or 0


async def _one(port: int, pdu: bytes) -> bytes:
    ((_, reply),) = await asyncio.to_thread(exchange, port, adu(pdu, tid=0x0102))
    return reply


@pytest.mark.parametrize(("name", "pdu", "reply"), [
    # FC23 read/write multiple registers, read quantity 0 (spec: 1..125) → 03
    ("fc23 read quantity 0", bytes([0x17, 0, 0, 0, 0, 0, 0, 0, 1, 2, 0, 0]), bytes([0x97, 0x03])),
    # FC23 write quantity 0 (spec: 1..121) → 03
    ("fc23 write quantity 0", bytes([0x17, 0, 0, 0, 1, 0, 0, 0, 0, 0]), bytes([0x97, 0x03])),
    # FC15 write multiple coils, quantity 1969 = 07B1h (spec: 1..1968), byte count 247 → 03
    ("fc15 quantity 1969", bytes([0x0F, 0, 0, 0x07, 0xB1, 247]) + bytes(247), bytes([0x8F, 0x03])),
    # FC5 write single coil with value 1234h (spec: only FF00h or 0000h) → 03
    ("fc5 value 1234h", bytes([0x05, 0, 0, 0x12, 0x34]), bytes([0x85, 0x03])),
    # FC16 byte count that does not match the quantity → 03
    ("fc16 byte count", bytes([0x10, 0, 0, 0, 1, 4, 0, 0, 0, 0]), bytes([0x90, 0x03])),
    # FC3 quantity 126 (spec: 1..125) → 03
    ("fc3 quantity 126", bytes([0x03, 0, 0, 0, 126]), bytes([0x83, 0x03])),
])
async def test_illegal_data_value_gets_exception_03(port: int, name: str, pdu: bytes, reply: bytes) -> None:
    assert await _one(port, pdu) == reply, name


async def test_fc5_legal_values_still_work(port: int) -> None:
    """FC5 FF00h sets the coil, 0000h clears it; the reply echoes the request (spec §6.5)."""
    on = bytes([0x05, 0, 8, 0xFF, 0x00])            # coil 8 = IF1
    assert await _one(port, on) == on
    assert await _one(port, bytes([0x01, 0, 8, 0, 1])) == bytes([0x01, 1, 1])
    off = bytes([0x05, 0, 8, 0, 0])
    assert await _one(port, off) == off
    assert await _one(port, bytes([0x01, 0, 8, 0, 1])) == bytes([0x01, 1, 0])


async def test_fc23_valid_request_is_served(port: int) -> None:
    """FC23 writes first, then reads (spec §6.17): IF flags written and read back in one request."""
    pdu = bytes([0x17, 0, 0, 0, 2, 0, 0, 0, 1, 2, 0x00, 0x81])   # HR0 := 0081h (IF1 + IF8)
    assert await _one(port, pdu) == bytes([0x17, 4, 0x00, 0x81, 0, 0])


async def test_pipelined_requests_in_one_write_are_all_answered_in_order(port: int) -> None:
    """Implementation Guide: a TCP stream is not framed by writes; 3 requests in one segment, 3 replies."""
    data = (adu(bytes([0x04, 0, 0, 0, 6]), tid=11) + adu(bytes([0x03, 0, 0, 0, 4]), tid=12)
            + adu(bytes([0x02, 0, 0, 0, 48]), tid=13))
    replies = await asyncio.to_thread(exchange, port, data, 3)
    assert [tid for tid, _ in replies] == [11, 12, 13]
    assert len(registers(replies[0][1])) == 6 and registers(replies[1][1]) == [0, 0, 0, 0]
    assert replies[2][1][:2] == bytes([0x02, 6])


def _session(port: int, *writes: bytes, replies: int) -> list[tuple[int, bytes]]:
    with socket.create_connection(("127.0.0.1", port), timeout=3) as s:
        for w in writes:
            s.sendall(w)
        return read_adus(s, replies)


async def test_mbap_length_zero_does_not_desync_the_stream(port: int) -> None:
    """An MBAP header claiming length 0 (no unit id, no PDU) is a 6-byte ADU that cannot be answered:
    it is dropped and the requests after it — same write or next — are answered."""
    bad = bytes([0x00, 0x21, 0x00, 0x00, 0x00, 0x00])
    good = adu(bytes([0x04, 0, 0, 0, 1]), tid=0x22)
    replies = await asyncio.to_thread(_session, port, bad + good, adu(bytes([0x03, 0, 0, 0, 1]), tid=0x23),
                                      replies=2)
    assert [tid for tid, _ in replies] == [0x22, 0x23]
    assert replies[0][1][:2] == bytes([0x04, 2]) and replies[1][1] == bytes([0x03, 2, 0, 0])


async def test_nonzero_protocol_id_is_dropped_and_the_connection_keeps_working(port: int) -> None:
    """Implementation Guide §3.1.3: protocol identifier 0 = MODBUS; another value is not a Modbus
    request — no reply, but the stream stays framed and the next request is answered."""
    foreign = adu(bytes([0x03, 0, 0, 0, 1]), tid=0x31, protocol=1)
    good = adu(bytes([0x03, 0, 0, 0, 1]), tid=0x32)
    replies = await asyncio.to_thread(_session, port, foreign + good, adu(bytes([0x04, 0, 5, 0, 1]), tid=0x33),
                                      replies=2)
    assert [tid for tid, _ in replies] == [0x32, 0x33]


async def test_a_request_split_over_writes_is_reassembled(port: int) -> None:
    data = adu(bytes([0x03, 0, 0, 0, 4]), tid=0x41)
    replies = await asyncio.to_thread(_session, port, data[:3], data[3:9], data[9:], replies=1)
    assert replies == [(0x41, bytes([0x03, 8]) + bytes(8))]


async def test_an_mbap_length_beyond_the_adu_limit_closes_the_connection(port: int) -> None:
    """Length 0xFFFF (an ADU is at most 260 bytes: length ≤ 254) cannot be framed: the server closes
    the connection instead of buffering 64 KiB that a length claims."""
    def run() -> bytes:
        with socket.create_connection(("127.0.0.1", port), timeout=3) as s:
            s.sendall(bytes([0, 1, 0, 0, 0xFF, 0xFF, 1, 3]))
            return s.recv(64)
    assert await asyncio.to_thread(run) == b""


@given(st.binary(min_size=1, max_size=253))
def test_check_pdu_answers_any_pdu(pdu: bytes) -> None:
    """Any PDU gets None (pymodbus may execute it) or one of the spec's exceptions 01, 02, 03 — never a crash."""
    code = check_pdu(pdu)
    assert code is None or int(code) in (1, 2, 3)
    if code is None:
        assert pdu[0] in (1, 2, 3, 4, 5, 6, 15, 16, 23)


async def test_garbage_then_a_request_on_a_fresh_connection(port: int) -> None:
    """Random bytes cost the sender its connection at worst, never the server (the next client is served)."""
    def garbage() -> None:
        with socket.create_connection(("127.0.0.1", port), timeout=3) as s:
            s.sendall(bytes(range(256)) * 8)
            s.settimeout(0.5)
            try:
                while s.recv(4096):
                    pass
            except (TimeoutError, ConnectionError):
                pass
    await asyncio.to_thread(garbage)
    reply = await _one(port, bytes([0x04, 0, 0, 0, 6]))
    assert reply[:2] == bytes([0x04, 12]) and len(reply) == 14


async def test_a_maximal_adu_and_the_next_request_in_one_write_are_both_answered(port: int) -> None:
    """Implementation Guide: an ADU is up to 260 bytes and a stream carries any number of them. A
    maximal ADU (length 254, here FC16 with a wrong byte count: exception 03) plus a request in one
    write (266 bytes) are both answered; pymodbus alone drops a receive buffer over 260 bytes (fuzz F1)."""
    big = adu(bytes([0x10, 0, 0, 0, 1, 248]) + bytes(247), tid=0x51)
    assert len(big) == 260
    data = big + adu(bytes([0x04, 0, 0, 0, 6]), tid=0x52)
    replies = await asyncio.to_thread(exchange, port, data, 2)
    assert [tid for tid, _ in replies] == [0x51, 0x52]
    assert replies[0][1] == bytes([0x90, 0x03]) and len(registers(replies[1][1])) == 6


async def test_many_pipelined_requests_in_one_write_are_all_answered(port: int) -> None:
    """40 requests (480 bytes) in one write: all 40 answered, in order (fuzz F1)."""
    data = b"".join(adu(bytes([0x03, 0, 0, 0, 4]), tid=0x100 + i) for i in range(40))
    replies = await asyncio.to_thread(exchange, port, data, 40)
    assert [tid for tid, _ in replies] == [0x100 + i for i in range(40)]


async def test_requests_before_an_unframeable_adu_are_answered_then_the_connection_closes(port: int) -> None:
    """A complete request, then in the same write an MBAP length over 254: the request is answered,
    then the connection is closed (fuzz F2)."""
    def run() -> tuple[list[tuple[int, bytes]], bytes]:
        with socket.create_connection(("127.0.0.1", port), timeout=3) as s:
            s.sendall(adu(bytes([0x04, 0, 0, 0, 6]), tid=0x61) + bytes([0, 0x62, 0, 0, 0x01, 0x00, 1, 3]))
            replies = read_adus(s, 1)
            return replies, s.recv(64)
    replies, rest = await asyncio.to_thread(run)
    assert [tid for tid, _ in replies] == [0x61] and len(registers(replies[0][1])) == 6
    assert rest == b""   # closed
