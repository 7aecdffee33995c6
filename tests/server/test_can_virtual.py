"""Issue 33 item 13: the batch send and read on python-can's ``virtual`` bus give what python-can's own
``send`` and ``recv`` give, message for message (the inferred CAN mapping, docs/driver.md "CAN")."""

from __future__ import annotations

import threading
import uuid
from typing import Any

import pytest

from pywsg.server import can_virtual

can = pytest.importorskip("can")

FIELDS = ("arbitration_id", "is_extended_id", "is_remote_frame", "is_error_frame", "channel", "dlc", "data",
          "is_fd", "is_rx", "bitrate_switch", "error_state_indicator")


def _buses(n: int, **kwargs: Any) -> list[Any]:
    channel = f"cv-{uuid.uuid4().hex[:8]}"
    return [can.Bus(interface="virtual", channel=channel, **kwargs) for _ in range(n)]


def _fields(msg: Any) -> tuple[Any, ...]:
    return (type(msg), *(getattr(msg, f) for f in FIELDS))


@pytest.mark.parametrize("own", [False, True])
def test_send_many_delivers_what_send_delivers_to_every_receiver(own: bool) -> None:
    tx, a, b = _buses(3, receive_own_messages=own)
    try:
        assert can_virtual.batchable(tx)
        chunks = [b"\xaa\xaa\xaa\x06\x00\x00\x0b\x00", b"\x01\x02", b""]
        for c in chunks:
            tx.send(can.Message(arbitration_id=0x02, data=c, is_extended_id=False))
        assert can_virtual.send_many(tx, 0x02, chunks)
        for rx in ([a, b, tx] if own else [a, b]):
            one = [rx.recv(1) for _ in chunks]
            batch = [rx.recv(1) for _ in chunks]
            assert [_fields(m) for m in batch] == [_fields(m) for m in one]
            assert all(m.timestamp > 0 for m in batch)
            assert len({id(m) for m in batch}) == len(batch)  # each receiver has its own objects
            assert rx.recv(0) is None
        if not own:
            assert tx.recv(0) is None
    finally:
        for bus in (tx, a, b):
            bus.shutdown()


def test_send_many_leaves_a_bounded_queue_or_a_wrapped_send_to_python_can() -> None:
    tx, rx = _buses(2, rx_queue_size=4)
    try:
        assert not can_virtual.send_many(tx, 0x02, [b"x"])  # python-can blocks or fails per message there
        assert rx.recv(0) is None
    finally:
        tx.shutdown()
        rx.shutdown()
    tx, rx = _buses(2)
    try:
        sent: list[Any] = []
        tx.send = sent.append  # a wrapper (fault injection, a logger) must see every message
        assert not can_virtual.send_many(tx, 0x02, [b"x"])
        assert rx.recv(0) is None
    finally:
        tx.shutdown()
        rx.shutdown()


def test_reader_hands_over_every_message_in_order_and_stops() -> None:
    tx, rx = _buses(2)
    got: list[Any] = []
    batches: list[int] = []
    done = threading.Event()

    def take(msgs: list[Any]) -> None:
        batches.append(len(msgs))
        got.extend(msgs)
        if len(got) >= 1000:
            done.set()

    reader = can_virtual.Reader(rx, take, name="cv-test-reader")
    try:
        for i in range(1000):
            tx.send(can.Message(arbitration_id=0x01, data=i.to_bytes(2, "little"), is_extended_id=False))
        assert done.wait(10)
        assert [int.from_bytes(m.data, "little") for m in got] == list(range(1000))
        assert len(batches) <= 1000
    finally:
        reader.stop()
        tx.shutdown()
        rx.shutdown()
    assert not any(t.name == "cv-test-reader" for t in threading.enumerate())
