"""Driver error paths and demultiplexing against a scripted raw TCP server: bad CRC from the device,
dropped connection, timeout with a late reply, pending + final in one segment, auto-updates
interleaved with replies, unsolicited frames."""

from __future__ import annotations

import builtins
import struct
import threading
import time

import pytest

from pywsg import AsyncGripper, Gripper
from pywsg.errors import ChecksumError, ConnectionLostError, ProtocolError, TimeoutError, WsgError
from pywsg.protocol import Command, Frame, GripperState, Status

from .rawserver import RawConn, RawServer

OK = Status.E_SUCCESS


def corrupt(frame_bytes: bytes) -> bytes:
    b = bytearray(frame_bytes)
    b[-1] ^= 0x5A  # wrong CRC
    return bytes(b)


def state_reply(state: int) -> bytes:
    return Frame.reply(Command.GET_GRIPPER_STATE, OK, bytes([state])).encode()


def echo_handler(conn: RawConn, f: Frame) -> None:
    """Answers 41h with HOLDING, 07h with success, 06h with its payload."""
    if f.command_id == Command.GET_GRIPPER_STATE:
        conn.send(state_reply(GripperState.HOLDING))
    elif f.command_id == Command.LOOP:
        conn.reply(f, OK, f.payload)
    elif f.command_id in (Command.DISCONNECT, Command.STOP):
        conn.reply(f, OK)


# ---------------------------------------------------------------- bad CRC from the device
def test_bad_crc_reply_raises_checksum_error_sync() -> None:
    first = [True]

    def handler(conn: RawConn, f: Frame) -> None:
        if f.command_id == Command.GET_GRIPPER_STATE and first[0]:
            first[0] = False
            conn.send(corrupt(state_reply(GripperState.HOLDING)))
        else:
            echo_handler(conn, f)

    with RawServer(handler) as srv, Gripper(srv.url, timeout=2) as g:
        with pytest.raises(ChecksumError) as ei:
            g.gripper_state()
        assert isinstance(ei.value, WsgError) and isinstance(ei.value, ProtocolError)
        assert ei.value.status == Status.E_CHECKSUM_ERROR and ei.value.command == Command.GET_GRIPPER_STATE
        assert not ei.value.from_device
        # the stream resynchronises: the next reply is accepted
        assert g.gripper_state() == GripperState.HOLDING


async def test_bad_crc_reply_raises_checksum_error_async() -> None:
    first = [True]

    def handler(conn: RawConn, f: Frame) -> None:
        if f.command_id == Command.LOOP and first[0]:
            first[0] = False
            conn.send(corrupt(Frame.reply(f.command_id, OK, f.payload).encode()))
        else:
            echo_handler(conn, f)

    with RawServer(handler) as srv:
        async with AsyncGripper(srv.url, timeout=30) as g:
            t0 = time.monotonic()
            with pytest.raises(ChecksumError):
                await g.loop(b"abc")
            assert time.monotonic() - t0 < 30  # failed by the bad reply, not by the 30 s timeout
            g.timeout = 2
            assert await g.loop(b"xyz") == b"xyz"


def test_device_checksum_error_status_maps_to_checksum_error() -> None:
    def handler(conn: RawConn, f: Frame) -> None:
        if f.command_id == Command.GET_GRIPPER_STATE:
            conn.reply(f, Status.E_CHECKSUM_ERROR)
        else:
            echo_handler(conn, f)

    with RawServer(handler) as srv, Gripper(srv.url) as g:
        with pytest.raises(ChecksumError) as ei:
            g.gripper_state()
        assert ei.value.from_device and ei.value.status_name == "E_CHECKSUM_ERROR"
        assert ei.value.meaning == "Checksum error"


# ---------------------------------------------------------------- dropped connection
def test_dropped_connection_fails_pending_motion_at_once_sync() -> None:
    def handler(conn: RawConn, f: Frame) -> None:
        if f.command_id == Command.PREPOSITION:
            conn.reply(f, Status.E_CMD_PENDING)
            threading.Timer(0.1, conn.close).start()
        else:
            echo_handler(conn, f)

    with RawServer(handler) as srv:
        g = Gripper(srv.url, timeout=1, motion_timeout=30)
        t0 = time.monotonic()
        with pytest.raises(ConnectionLostError) as ei:
            g.move(50, 100)
        assert time.monotonic() - t0 < 30  # by the drop, not the 30 s motion timeout
        assert isinstance(ei.value, ConnectionError) and isinstance(ei.value, WsgError)
        assert ei.value.command == Command.PREPOSITION
        assert not g.connected
        with pytest.raises(ConnectionLostError):
            g.width()
        g.close()


async def test_dropped_connection_fails_all_pending_calls_async() -> None:
    def handler(conn: RawConn, f: Frame) -> None:
        if f.command_id == Command.GRIP_PART:
            conn.reply(f, Status.E_CMD_PENDING)
        elif f.command_id == Command.GET_TEMPERATURE:
            conn.close()  # drop while a grip runs and this request waits

    with RawServer(handler) as srv:
        g = await AsyncGripper.open(srv.url, timeout=10, motion_timeout=30)
        motion = await g.grip(20, 50, wait=False)
        t0 = time.monotonic()
        with pytest.raises(ConnectionLostError):
            await g.temperature()
        with pytest.raises(ConnectionLostError):
            await motion.wait()
        assert time.monotonic() - t0 < 10  # by the drop, not the 10 s request timeout
        assert not g.connected
        await g.close()


def test_connect_refused_is_connection_lost_error() -> None:
    with RawServer(echo_handler) as srv:
        url = srv.url
    with pytest.raises(ConnectionLostError):
        Gripper(url, connect_timeout=1)


# ---------------------------------------------------------------- timeout
def test_timeout_then_late_reply_is_not_given_to_the_next_call() -> None:
    n = [0]

    def handler(conn: RawConn, f: Frame) -> None:
        if f.command_id == Command.GET_GRIPPER_STATE:
            n[0] += 1
            if n[0] == 1:  # answer the first request late, with a value the second must not see
                threading.Timer(0.3, conn.send, args=(state_reply(GripperState.NO_PART),)).start()
            else:
                conn.send(state_reply(GripperState.HOLDING))
        else:
            echo_handler(conn, f)

    with RawServer(handler) as srv, Gripper(srv.url, timeout=0.1) as g:
        t0 = time.monotonic()
        with pytest.raises(TimeoutError) as ei:
            g.gripper_state()
        assert time.monotonic() - t0 > 0.09  # TimeoutError, not the reply sent after 0.3 s: it did not wait
        assert isinstance(ei.value, builtins.TimeoutError) and isinstance(ei.value, WsgError)
        assert ei.value.status == Status.E_TIMEOUT and not ei.value.from_device
        time.sleep(0.35)  # the late NO_PART arrives now
        g.timeout = 1.0
        assert g.gripper_state() == GripperState.HOLDING
        assert g.demux.late == 1


async def test_timeout_async_on_every_wait() -> None:
    def handler(conn: RawConn, f: Frame) -> None:
        if f.command_id == Command.HOMING:
            conn.reply(f, Status.E_CMD_PENDING)  # and never a final
        elif f.command_id == Command.GET_SYSTEM_STATE:
            conn.reply(f, OK, struct.pack("<I", 1))
        elif f.command_id == Command.DISCONNECT:
            conn.reply(f, OK)
        # 46h: never answered

    with RawServer(handler) as srv:
        async with AsyncGripper(srv.url, timeout=0.1) as g:
            with pytest.raises(TimeoutError):
                await g.temperature()
            m = await g.home(wait=False)
            with pytest.raises(TimeoutError) as ei:
                await m.wait(0.1)
            assert "motion not finished" in str(ei.value)
            assert not m.done()


# ---------------------------------------------------------------- demultiplexing
def test_pending_and_final_in_one_segment_sync() -> None:
    def handler(conn: RawConn, f: Frame) -> None:
        if f.command_id == Command.RELEASE_PART:
            conn.send(Frame.reply(f.command_id, Status.E_CMD_PENDING).encode() + Frame.reply(f.command_id, OK).encode())
        else:
            echo_handler(conn, f)

    with RawServer(handler) as srv, Gripper(srv.url) as g:
        m = g.release(50, 100)
        assert m.done() and m.status == Status.E_SUCCESS


async def test_auto_updates_interleaved_with_replies_async() -> None:
    """A subscription to 43h and an explicit 41h read: update packets arrive between request and reply."""

    def handler(conn: RawConn, f: Frame) -> None:
        if f.command_id == Command.GET_OPENING_WIDTH:
            conn.reply(f, OK, struct.pack("<f", 10.0))
        elif f.command_id == Command.GET_GRIPPER_STATE:
            w = b"".join(Frame.reply(0x43, OK, struct.pack("<f", 11.0 + i)).encode() for i in range(3))
            conn.send(w + state_reply(GripperState.GRIPPING) + w)
        else:
            echo_handler(conn, f)

    with RawServer(handler) as srv:
        async with AsyncGripper(srv.url) as g:
            s = await g.subscribe("width", period=0.01)
            assert await g.gripper_state() == GripperState.GRIPPING
            samples = [await s.get(1) for _ in range(7)]
            assert [x.value for x in samples] == [10.0, 11.0, 12.0, 13.0, 11.0, 12.0, 13.0]
            assert all(x.command == Command.GET_OPENING_WIDTH for x in samples)


def test_motion_final_and_second_motion_refusal_same_id() -> None:
    """A second 21h while one runs: E_ALREADY_RUNNING answers the request, E_SUCCESS ends the motion."""

    def handler(conn: RawConn, f: Frame) -> None:
        if f.command_id == Command.PREPOSITION:
            if len([r for r in srv.requests if r.command_id == Command.PREPOSITION]) == 1:
                conn.reply(f, Status.E_CMD_PENDING)
            else:  # refusal and the first motion's final in one segment
                conn.send(Frame.reply(0x21, Status.E_ALREADY_RUNNING).encode() + Frame.reply(0x21, OK).encode())
        elif f.command_id == Command.GET_SYSTEM_STATE:
            conn.reply(f, OK, struct.pack("<I", 3))
        else:
            echo_handler(conn, f)

    with RawServer(handler) as srv, Gripper(srv.url) as g:
        m = g.move(30, 100, wait=False)
        with pytest.raises(WsgError) as ei:
            g.move(40, 100)
        assert ei.value.status == Status.E_ALREADY_RUNNING
        m.wait(1)
        assert m.status == Status.E_SUCCESS


def test_unsolicited_frame_is_counted_not_misrouted() -> None:
    def handler(conn: RawConn, f: Frame) -> None:
        if f.command_id == Command.LOOP:
            conn.send(Frame.reply(0x45, OK, struct.pack("<f", 3.0)).encode())  # nobody asked
            conn.reply(f, OK, f.payload)
        else:
            echo_handler(conn, f)

    with RawServer(handler) as srv, Gripper(srv.url) as g:
        assert g.loop(b"hello") == b"hello"
        assert g.demux.unsolicited == 1


def test_comm_log_hook_sees_every_frame_decoded() -> None:
    with RawServer(echo_handler) as srv, Gripper(srv.url) as g:
        entries = []
        g.on_frame = entries.append
        g.gripper_state()
        assert [e.direction for e in entries] == ["tx", "rx"]
        assert "GET_GRIPPER_STATE" in entries[0].text and "request" in entries[0].text
        assert "HOLDING" in entries[1].text and "E_SUCCESS" in entries[1].text
        assert entries[1].hex.startswith("AA AA AA 41")
        assert entries[0].time <= entries[1].time


def test_debug_logging_of_frames(caplog: pytest.LogCaptureFixture) -> None:
    import logging

    with RawServer(echo_handler) as srv, Gripper(srv.url) as g:
        with caplog.at_level(logging.DEBUG, logger="pywsg.client.frames"):
            g.loop(b"\x01\x02")
        lines = [r.getMessage() for r in caplog.records if r.name == "pywsg.client.frames"]
        assert any("LOOP request" in x for x in lines) and any("LOOP reply E_SUCCESS" in x for x in lines)


def test_disconnect_announced_on_close() -> None:
    with RawServer(echo_handler) as srv:
        with Gripper(srv.url) as g:
            g.loop()
        srv.wait_requests(2)
        assert srv.requests[-1].command_id == Command.DISCONNECT
