"""The drivers' fast paths keep their promises: one shared timer still times every asyncio wait
(short after long, many calls), kernel socket timeouts follow the timeout asked for, the cache of
verified frames never lets a bad CRC through, decoded results follow the reply bytes, the comm-log
hook sees calls made after it is installed, and concurrent threads on one ``Gripper`` each get their
own replies."""

from __future__ import annotations

import asyncio
import threading
import time

import pytest

from pywsg import AsyncGripper, Gripper
from pywsg.errors import ChecksumError, TimeoutError
from pywsg.protocol import Command, Frame, GripperState, Status

from .rawserver import RawConn, RawServer
from .test_raw_paths import corrupt, echo_handler, state_reply

OK = Status.E_SUCCESS


# ---------------------------------------------------------------- asyncio: one timer for all waits
async def test_async_short_timeout_after_long_one_fires_on_time() -> None:
    def handler(conn: RawConn, f: Frame) -> None:
        if f.command_id == Command.LOOP:
            conn.reply(f, OK, f.payload)
        elif f.command_id == Command.DISCONNECT:
            conn.reply(f, OK)
        # 41h and 46h: never answered

    with RawServer(handler) as srv:
        async with AsyncGripper(srv.url, timeout=0.6) as g:
            for _ in range(600):  # many answered calls: their deadlines must not pile up or fire
                assert await g.loop(b"x") == b"x"
            assert len(g._timed) <= 256
            t0 = time.monotonic()
            long = asyncio.ensure_future(g.gripper_state())  # deadline in 0.6 s
            await asyncio.sleep(0)
            g.timeout = 0.1
            with pytest.raises(TimeoutError):
                await g.temperature()  # earlier deadline than the one armed: the timer moves up
            # before the 0.6 s deadline armed first: the timer moved up (only the lower bound is the machine's)
            assert 0.09 < time.monotonic() - t0 < 0.6
            with pytest.raises(TimeoutError) as ei:
                await long
            assert time.monotonic() - t0 > 0.55
            assert "0.6 s" in str(ei.value)
            g.timeout = 1.0
            assert await g.loop(b"after") == b"after"


# ---------------------------------------------------------------- blocking: kernel socket timeouts
def test_sync_timeouts_follow_the_timeout_asked_for() -> None:
    def handler(conn: RawConn, f: Frame) -> None:
        if f.command_id == Command.GET_GRIPPER_STATE:  # answered after 0.3 s
            threading.Timer(0.3, conn.send, args=(state_reply(GripperState.HOLDING),)).start()
        elif f.command_id != Command.GET_TEMPERATURE:  # 46h: never answered
            echo_handler(conn, f)

    with RawServer(handler) as srv, Gripper(srv.url, timeout=0.1) as g:
        t0 = time.monotonic()
        with pytest.raises(TimeoutError):
            g.temperature()
        assert 0.095 < time.monotonic() - t0 < 1.0  # the 0.1 s asked for, not the default 1 s
        g.timeout = 2.0  # longer than the receive timeout set: the 0.3 s reply must still arrive
        assert g.gripper_state() == GripperState.HOLDING
        g.timeout = 0.05  # shorter again: must not wait the 2 s still set in the kernel
        t0 = time.monotonic()
        with pytest.raises(TimeoutError):
            g.temperature()
        assert 0.045 < time.monotonic() - t0 < 2.0  # not the 2 s still set in the kernel


# ---------------------------------------------------------------- verified-frame cache
def _bad_state_handler(conn: RawConn, f: Frame) -> None:
    if f.command_id == Command.GET_GRIPPER_STATE:
        conn.send(corrupt(state_reply(GripperState.NO_PART)))
    else:
        echo_handler(conn, f)


def test_frame_accepted_without_verification_is_not_trusted_by_a_verifying_client() -> None:
    with RawServer(_bad_state_handler) as srv:
        with Gripper(srv.url, timeout=1, verify_checksum=False) as lax:
            assert lax.gripper_state() == GripperState.NO_PART  # CRC ignored, as configured
            assert lax.gripper_state() == GripperState.NO_PART
        with Gripper(srv.url, timeout=1) as strict, pytest.raises(ChecksumError):
            strict.gripper_state()


async def test_frame_cache_async_checks_crc_after_good_frames() -> None:
    n = [0]

    def handler(conn: RawConn, f: Frame) -> None:
        if f.command_id == Command.GET_GRIPPER_STATE:
            n[0] += 1
            good = state_reply(GripperState.HOLDING)
            conn.send(good if n[0] != 3 else corrupt(good))
        else:
            echo_handler(conn, f)

    with RawServer(handler) as srv:
        async with AsyncGripper(srv.url, timeout=1) as g:
            assert await g.gripper_state() == GripperState.HOLDING
            assert await g.gripper_state() == GripperState.HOLDING  # served from the cache
            with pytest.raises(ChecksumError):
                await g.gripper_state()  # same reply, one CRC byte changed
            assert await g.gripper_state() == GripperState.HOLDING


# ---------------------------------------------------------------- decoded results follow the bytes
def test_results_follow_each_reply() -> None:
    seq = [GripperState.HOLDING, GripperState.NO_PART, GripperState.HOLDING, GripperState.IDLE]
    n = [0]

    def handler(conn: RawConn, f: Frame) -> None:
        if f.command_id == Command.GET_GRIPPER_STATE:
            conn.send(state_reply(seq[n[0] % len(seq)]))
            n[0] += 1
        else:
            echo_handler(conn, f)

    with RawServer(handler) as srv, Gripper(srv.url, timeout=1) as g:
        got = [g.gripper_state() for _ in range(8)]
    assert got == seq * 2


# ---------------------------------------------------------------- comm log installed later
def test_hook_installed_after_fast_calls_sees_the_next_calls() -> None:
    with RawServer(echo_handler) as srv, Gripper(srv.url, timeout=1) as g:
        for _ in range(5):
            g.gripper_state()
        seen: list[str] = []
        g.on_frame = lambda e: seen.append(e.text)
        g.gripper_state()
        g.on_frame = None
        g.gripper_state()
    assert len(seen) == 2, seen
    assert seen[0].startswith("tx 41h") and seen[1].startswith("rx 41h") and "HOLDING" in seen[1]


# ---------------------------------------------------------------- threads sharing one Gripper
def test_threads_share_one_gripper_and_get_their_own_replies(sim: object) -> None:
    url = sim.url("tcp")  # type: ignore[attr-defined]
    errors: list[BaseException] = []
    with Gripper(url, timeout=2) as g:
        def worker(tag: bytes) -> None:
            try:
                for i in range(150):
                    data = tag + str(i).encode()
                    assert g.loop(data) == data
                    assert g.gripper_state() in tuple(GripperState)
            except BaseException as exc:  # reported below
                errors.append(exc)

        threads = [threading.Thread(target=worker, args=(bytes([65 + k]),)) for k in range(4)]
        for t in threads:
            t.start()
        for t in threads:
            t.join(30)
        assert not any(t.is_alive() for t in threads)
        assert g.demux.outstanding() == 0
    assert not errors, errors[:3]


# ---------------------------------------------------------------- the waiter-less call's fallbacks
def test_blocking_call_fallbacks_split_other_id_first_two_in_one_segment() -> None:
    loop_reply = Frame.reply(Command.LOOP, OK, b"zz").encode()
    n = [0]

    def handler(conn: RawConn, f: Frame) -> None:
        if f.command_id != Command.GET_GRIPPER_STATE:
            echo_handler(conn, f)
            return
        n[0] += 1
        reply = state_reply(GripperState.HOLDING if n[0] != 3 else GripperState.NO_PART)
        if n[0] == 1:  # split in two segments: the first read is a partial frame
            conn.send(reply[:4])
            time.sleep(0.02)
            conn.send(reply[4:])
        elif n[0] == 2:  # a frame of another ID first (unsolicited), then the reply
            conn.send(loop_reply)
            time.sleep(0.02)
            conn.send(reply)
        elif n[0] == 3:  # the reply and an unsolicited frame in one segment
            conn.send(reply + loop_reply)
        else:
            conn.send(reply)

    with RawServer(handler) as srv, Gripper(srv.url, timeout=1) as g:
        assert g.gripper_state() == GripperState.HOLDING
        assert g.gripper_state() == GripperState.HOLDING
        assert g.demux.unsolicited == 1
        assert g.gripper_state() == GripperState.NO_PART
        assert g.gripper_state() == GripperState.HOLDING
        assert g.demux.unsolicited == 2
        assert g.demux.outstanding() == 0


def test_blocking_call_timeout_without_waiter_leaves_a_ghost() -> None:
    n = [0]
    timed_out, late_sent = threading.Event(), threading.Event()

    def send_late(conn: RawConn) -> None:  # the first reply, only after the call gave up (no race with load)
        timed_out.wait(30)
        conn.send(state_reply(GripperState.NO_PART))
        late_sent.set()

    def handler(conn: RawConn, f: Frame) -> None:
        if f.command_id == Command.GET_GRIPPER_STATE:
            n[0] += 1
            if n[0] == 1:
                threading.Thread(target=send_late, args=(conn,), daemon=True).start()
            else:
                late_sent.wait(30)  # the late reply is on the wire before this one
                conn.send(state_reply(GripperState.HOLDING))
        else:
            echo_handler(conn, f)

    with RawServer(handler) as srv, Gripper(srv.url, timeout=0.1) as g:
        assert g.demux.alone(Command.GET_GRIPPER_STATE)  # so the first call takes the waiter-less path
        with pytest.raises(TimeoutError):
            g.gripper_state()
        timed_out.set()
        g.timeout = 30  # generous: the second reply follows the late one at once
        assert g.gripper_state() == GripperState.HOLDING  # the late NO_PART went to the ghost
        assert g.demux.late == 1
