"""The hot-path shortcuts (requests parsed once per distinct bytes, reused value frames) change no answer."""

from __future__ import annotations

import struct
from typing import Any

import pytest

from pywsg.protocol import CATALOG, Frame, Status

from .conftest import SimThread, TcpClient, UdpClient, bad_crc

GET_ACC = Frame(0x31).encode()


def set_acc(value: float) -> bytes:
    return Frame(0x30, CATALOG[0x30].encode_request(acceleration=value)).encode()


def acc_of(reply: Frame) -> float:
    assert reply.status == Status.E_SUCCESS, reply
    return float(struct.unpack("<f", reply.payload[2:6])[0])


def set_crc_check(sim: SimThread, on: bool) -> None:
    g = sim.g.gripper
    sim.call(lambda: g.apply_settings(g.settings.updated(crc_check=on)))


@pytest.mark.parametrize("kind", ["tcp", "udp"])
def test_repeated_request_bytes_get_current_answers(sim: SimThread, kind: str) -> None:
    c: Any = TcpClient(sim.g.tcp_port) if kind == "tcp" else UdpClient(sim.g.udp_port)
    try:
        first = [acc_of(c.reply(0x31)) for _ in range(3) if c.send(GET_ACC) is None]
        assert len(set(first)) == 1
        c.send(set_acc(first[0] * 0.9))
        assert c.reply(0x30).status == Status.E_SUCCESS
        c.send(GET_ACC)  # the very same bytes as before: the new value, not a remembered answer
        assert acc_of(c.reply(0x31)) == pytest.approx(first[0] * 0.9, rel=1e-6)
    finally:
        c.close()


@pytest.mark.parametrize("kind", ["tcp", "udp"])
def test_crc_setting_still_decides_for_repeated_bytes(sim: SimThread, kind: str) -> None:
    good, bad = GET_ACC, bad_crc(GET_ACC)
    c: Any = TcpClient(sim.g.tcp_port) if kind == "tcp" else UdpClient(sim.g.udp_port)
    try:
        set_crc_check(sim, False)
        for _ in range(2):  # a wrong checksum is accepted while the check is off, repeatedly
            c.send(bad)
            assert c.reply(0x31).status == Status.E_SUCCESS
            c.send(good)
            assert c.reply(0x31).status == Status.E_SUCCESS
        set_crc_check(sim, True)
        for _ in range(2):  # the same bytes once it is on again: refused every time
            c.send(bad)
            assert c.reply(0x31).status == Status.E_CHECKSUM_ERROR
            c.send(good)
            assert c.reply(0x31).status == Status.E_SUCCESS
    finally:
        c.close()


def test_split_repeat_of_a_known_request_is_parsed_whole(sim: SimThread) -> None:
    """Bytes of a known request arriving after a partial frame are not taken for the request."""
    c = TcpClient(sim.g.tcp_port)
    try:
        c.send(GET_ACC)
        assert c.reply(0x31).status == Status.E_SUCCESS
        c.send(GET_ACC[:5])  # half a frame buffered in the parser ...
        c.send(GET_ACC[5:] + GET_ACC)  # ... completed, then the known bytes again
        assert c.reply(0x31).status == Status.E_SUCCESS
        assert c.reply(0x31).status == Status.E_SUCCESS
    finally:
        c.close()
