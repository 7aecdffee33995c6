"""Network faults (issue 27 item 1) as a user meets them: switched at runtime through ``wsg_sim.world.net``,
and what pywsg's own driver does under each — its timeout, ``reconnect=True``, the error it raises.

The gripper side runs on a manual clock (no motion here needs time); the faults themselves act on the
real wire, so the delays used are short (tens of ms) and every bound is a lower bound or a ratio.
"""

from __future__ import annotations

import socket
import time

import pytest

from pywsg.client import Gripper
from pywsg.errors import ConnectionLostError, TimeoutError, WsgError
from pywsg.protocol import Command, Frame, FrameParser, SystemFlag
from pywsg.server.netfault import NetFaults
from pywsg.testing import SimThread, WorldError

pytestmark = pytest.mark.wsg_sim(clock="manual")

# 000 §3.1.1 LOOP: the payload comes back; a request frame built by the protocol package
LOOP = Frame(Command.LOOP, b"ping").encode()


def _timed(fn: object) -> float:
    t = time.monotonic()
    fn()  # type: ignore[operator]
    return time.monotonic() - t


def test_latency_makes_a_short_timeout_fire_and_a_long_one_wait(wsg_sim: SimThread) -> None:
    with Gripper(wsg_sim.url, timeout=2.0) as g:
        base = _timed(g.width)
        assert wsg_sim.world.net("latency", ms=150, jitter=20) == "latency 150 ms ± 20 ms"
        assert wsg_sim.world.state()["net"] == {"latency": {"ms": 150.0, "jitter": 20.0}}
        slow = _timed(g.width)
        assert slow >= 0.13 > base  # 150 ms - 20 ms jitter at least
        g.timeout = 0.05
        with pytest.raises(TimeoutError, match=r"no reply within 0\.05 s"):
            g.width()
        g.timeout = 2.0
        time.sleep(0.2)  # the late reply of the timed-out request arrives and is dropped by the driver
        wsg_sim.world.net("latency", on=False)
        assert g.width() == 0.0  # the link works again, no stale reply mixed up
        assert wsg_sim.world.state()["net"] == {}


def test_bandwidth_limit_slows_replies_by_their_size(wsg_sim: SimThread) -> None:
    wsg_sim.world.net("bandwidth", rate=200)  # bytes/s
    with Gripper(wsg_sim.url, timeout=5.0) as g:
        short = _timed(lambda: g.loop(b"x"))          # 11-byte reply: >= 55 ms
        long = _timed(lambda: g.loop(b"x" * 40))      # 50-byte reply: >= 250 ms
        assert short >= 11 / 200 * 0.9
        assert long >= 50 / 200 * 0.9
        assert long > 2 * short  # the time grows with the reply's size


def test_slicer_cuts_replies_into_segments_the_driver_reassembles(wsg_sim: SimThread) -> None:
    wsg_sim.world.net("slicer", size=2, gap=15)
    with Gripper(wsg_sim.url, timeout=5.0) as g:
        assert g.loop(b"sliced") == b"sliced"
    with socket.create_connection(("127.0.0.1", wsg_sim.g.tcp_port), timeout=5) as s:
        s.sendall(LOOP)
        chunks: list[bytes] = []
        parser = FrameParser()
        frames: list[Frame] = []
        while not frames:
            chunk = s.recv(4096)
            assert chunk, "the sim closed the connection"
            chunks.append(chunk)
            frames += [e for e in parser.feed(chunk) if isinstance(e, Frame)]
        assert frames[0].payload == b"\x00\x00ping"
        assert len(chunks) >= 3  # 14 bytes in 2-byte segments 15 ms apart never come in one read


def test_reset_by_the_gripper_raises_connection_lost_and_reconnect_finds_fast_stop(wsg_sim: SimThread) -> None:
    with Gripper(wsg_sim.url, timeout=2.0) as g:
        assert g.loop(b"a") == b"a"
        wsg_sim.world.net("reset", timeout=0)  # reset now, and every new connection at once
        with pytest.raises(ConnectionLostError):
            g.loop(b"b")
    assert wsg_sim.world.state()["fast_stop"]  # 000 §1.4.2: the session ended without 07h
    wsg_sim.world.net("reset", on=False)
    seen: list[SystemFlag] = []
    with Gripper(wsg_sim.url, timeout=2.0, reconnect=True) as g:
        g.on_reconnect = seen.append
        g.loop(b"c")  # a round trip: the sim has taken the connection (not only the kernel)
        wsg_sim.world.net("reset", timeout=0)
        wsg_sim.world.net("reset", on=False)  # one reset, then the network is healthy again
        try:  # a call that meets the reset fails at once, even with reconnect=True; one made after the
            g.system_state()  # driver saw the connection go waits for its reconnection
        except ConnectionLostError:
            pass
        flags = g.system_state()
        assert flags & SystemFlag.SF_FAST_STOP
        deadline = time.monotonic() + 10  # on_reconnect runs on the driver's reconnecting thread
        while not seen and time.monotonic() < deadline:
            time.sleep(0.01)
        assert seen and seen[0] & SystemFlag.SF_FAST_STOP  # reported, never acknowledged by the driver


def test_silent_gripper_times_out_with_the_connection_open(wsg_sim: SimThread) -> None:
    with Gripper(wsg_sim.url, timeout=0.1) as g:
        wsg_sim.world.net("silent")
        with pytest.raises(TimeoutError):
            g.loop(b"hello?")
        assert len(wsg_sim.g.tcp.connections) == 1  # type: ignore[union-attr]  # still open
        assert wsg_sim.world.state()["fast_stop"] is False  # nothing was lost, so no FAST STOP
        wsg_sim.world.net("silent", on=False)
        assert g.width() == 0.0  # another command: answered at once
        # The driver keeps a "ghost" for the timed-out LOOP's late reply (client/demux.py, 5 s): the
        # silent gripper never sends it, so the next LOOP's reply is taken for it and that call times
        # out too — but leaves no ghost (its reply was the one taken): the one after is in step again
        with pytest.raises(TimeoutError):
            g.loop(b"back")
        assert g.loop(b"back") == b"back"
        assert g.loop(b"and again") == b"and again"


def test_silent_with_timeout_closes_the_connection(wsg_sim: SimThread) -> None:
    with Gripper(wsg_sim.url, timeout=1.0) as g:
        wsg_sim.world.net("silent", timeout=0.05)
        with pytest.raises((ConnectionLostError, TimeoutError)):
            g.loop(b"x")
    deadline = time.monotonic() + 5
    while wsg_sim.g.tcp.connections and time.monotonic() < deadline:  # type: ignore[union-attr]
        time.sleep(0.01)
    assert not wsg_sim.g.tcp.connections, "the silent gripper did not close the connection"  # type: ignore[union-attr]


def test_udp_datagrams_dropped_give_timeouts_and_reordered_ones_swap(wsg_sim: SimThread) -> None:
    wsg_sim.world.net("drop", p=1.0)
    with Gripper(wsg_sim.udp_url, timeout=0.1) as g:
        with pytest.raises(TimeoutError):
            g.loop(b"lost")
        wsg_sim.world.net("drop", on=False)
        assert g.width() == 0.0  # another command: answered at once
        with pytest.raises(TimeoutError):
            g.loop(b"found")  # its reply went to the lost LOOP's ghost (see the silent test) ...
        assert g.loop(b"found") == b"found"  # ... and then none is left
    wsg_sim.world.net("reorder", p=1.0)
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.settimeout(5)
        port = wsg_sim.g.udp_port
        s.sendto(Frame(Command.LOOP, b"first").encode(), ("127.0.0.1", port))
        time.sleep(0.01)  # the held-back reply waits for the next one (at most 50 ms)
        s.sendto(Frame(Command.LOOP, b"second").encode(), ("127.0.0.1", port))
        got = []
        for _ in range(2):
            frame = next(e for e in FrameParser().feed(s.recv(100)) if isinstance(e, Frame))
            got.append(frame.payload[2:])
    assert got == [b"second", b"first"]


def test_serial_line_garbles_bytes_and_the_driver_reports_it(wsg_sim: SimThread) -> None:
    url = wsg_sim.serial_url
    with Gripper(url, timeout=0.3) as g:
        assert g.loop(b"clean") == b"clean"
        wsg_sim.world.net("garble", p=0.3, seed=7)
        errors = []
        for _ in range(5):
            try:
                g.loop(b"noisy line")
            except WsgError as exc:  # a checksum error or a frame never recognised: a timeout
                errors.append(exc)
        assert errors, "no request failed on a line that garbles 30 % of the bytes"
        assert wsg_sim.world.state()["net"] == {"garble": {"p": 0.3}}
        kinds = {type(e).__name__ for e in errors}
        assert kinds <= {"TimeoutError", "BadChecksumReply", "ChecksumError"}, kinds
        wsg_sim.world.net("clear")
        g.timeout = 10.0  # s: the short timeout was for the garbled line; a clean one answers, however loaded
        g.reconnect()  # forget the ghosts of the timed-out calls (see the silent test)
        assert g.loop(b"clean again") == b"clean again"


def test_bad_network_fault_parameters_are_refused_with_the_field_named(wsg_sim: SimThread) -> None:
    with pytest.raises(WorldError, match="kind: must be one of latency"):
        wsg_sim.world.net("lag")
    with pytest.raises(WorldError, match=r"p: must be within 0\.\.1"):
        wsg_sim.world.net("drop", p=2)
    with pytest.raises(WorldError, match="rate: not a parameter of latency"):
        wsg_sim.world.net("latency", rate=5)
    assert wsg_sim.world.state()["net"] == {}  # nothing half-applied


def test_fault_free_link_takes_the_fast_path() -> None:
    nf = NetFaults()
    written: list[bytes] = []
    from pywsg.server.netfault import Shaper

    shaper = Shaper(nf, written.append)
    shaper.send(b"abc")  # no loop needed: nothing is scheduled when every fault is off
    assert written == [b"abc"] and not shaper.busy
    nf.set("garble", {"p": 1.0})
    nf.clear()
    assert not nf.active


async def test_async_driver_under_a_silent_gripper(wsg_sim: SimThread) -> None:
    """AsyncGripper the same way: a timeout, one more for the lost reply's ghost, then in step."""
    from pywsg.client import AsyncGripper

    async with AsyncGripper(wsg_sim.url, timeout=0.1) as g:
        assert await g.loop(b"a") == b"a"
        wsg_sim.world.net("silent")
        with pytest.raises(TimeoutError):
            await g.loop(b"b")
        wsg_sim.world.net("silent", on=False)
        with pytest.raises(TimeoutError):
            await g.loop(b"c")  # its reply went to the ghost of "b"
        assert await g.loop(b"d") == b"d"


def test_can_frames_dropped_and_garbled() -> None:
    """On the (inferred) CAN interface the faults act on each 8-byte CAN frame: a lost fragment spoils a reply."""
    pytest.importorskip("can")
    import uuid

    channel = f"wsg-{uuid.uuid4().hex[:8]}"
    with SimThread(clock="manual", tcp_port=None, udp_port=None, can_channel=channel) as sim, \
            Gripper(f"can://{channel}?interface=virtual", timeout=0.2) as g:
        assert g.loop(b"over can") == b"over can"
        sim.world.net("drop", p=1.0)
        with pytest.raises(TimeoutError):
            g.width()
        sim.world.net("clear")
        assert g.temperature() > 0  # another command: in step at once


def test_a_slow_fault_holds_back_a_bounded_amount() -> None:
    """A client flooding a 1-byte/s link: the sim holds at most MAX_PENDING bytes, dropping whole writes."""
    import asyncio

    from pywsg.server.netfault import MAX_PENDING, Shaper

    async def flood() -> tuple[int, int]:
        nf = NetFaults()
        nf.set("bandwidth", {"rate": 1})
        written: list[bytes] = []
        shaper = Shaper(nf, written.append)
        for _ in range(10_000):
            shaper.send(b"x" * 100)
        held = shaper._pending_bytes
        shaper.close()
        return held, nf.counts["overflow"]

    held, overflow = asyncio.run(flood())
    assert held <= MAX_PENDING
    assert overflow == 10_000 - MAX_PENDING // 100
