"""The driver over CAN (inferred mapping, docs/driver.md "CAN"; 000 §1.1 names CAN as an interface):
``Gripper`` and ``AsyncGripper`` against ``wsg sim``'s CAN side on python-can's ``virtual`` bus (sim
and driver in one process, separate threads), and across processes on a kernel ``vcan`` interface
where this machine has one."""

from __future__ import annotations

import asyncio
import subprocess
import sys
import threading
import time
import uuid
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from pywsg import AsyncGripper, Gripper
from pywsg.client.url import parse_url
from pywsg.errors import BadChecksumReply, RangeError, TimeoutError, WsgError
from pywsg.protocol import Command, GripperState

from .conftest import SimThread

can = pytest.importorskip("can")


def channel() -> str:
    return f"wsg-{uuid.uuid4().hex[:8]}"


@pytest.fixture
def can_sim(sim_factory: Callable[..., SimThread]) -> tuple[SimThread, str]:
    ch = channel()
    st = sim_factory(tcp_port=None, udp_port=None, can_channel=ch)
    return st, f"can://{ch}?interface=virtual"


# -- URLs -------------------------------------------------------------------------------------------


def test_can_urls_parse_with_python_can_options() -> None:
    ep = parse_url("can://can0?interface=socketcan&bitrate=1000000&request_id=0x10&reply_id=0x11&fd=true")
    assert (ep.scheme, ep.path, ep.interface, ep.bitrate) == ("can", "can0", "socketcan", 1_000_000)
    assert (ep.request_id, ep.reply_id, ep.extended, ep.can_options) == (0x10, 0x11, False, (("fd", "true"),))
    assert parse_url(str(ep)) == ep
    ep = parse_url("can://PCAN_USBBUS1?interface=pcan&extended=1&request_id=0x18FF0001&reply_id=0x18FF0002")
    assert ep.extended and ep.request_id == 0x18FF0001 and ep.path == "PCAN_USBBUS1"
    assert parse_url("can://vcan0").interface == ""  # python-can's own configuration decides


@pytest.mark.parametrize(("url", "words"), [
    ("can://", "no CAN channel"),
    ("can://can0?request_id=0x800", "11-bit"),
    ("can://can0?request_id=x", "not an integer"),
    ("can://can0?request_id=2", "same identifier"),
    ("can://can0?extended=maybe", "use 0 or 1"),
    ("can://can0?bitrate=-5", "negative"),
])
def test_bad_can_urls_say_what_is_wrong(url: str, words: str) -> None:
    with pytest.raises(ValueError, match=words):
        parse_url(url)


def test_an_unknown_interface_is_a_clear_connection_error() -> None:
    with pytest.raises(WsgError, match="cannot open CAN channel"):
        Gripper("can://x?interface=no-such-interface")


# -- blocking and asyncio driver on the virtual bus ---------------------------------------------------


def test_gripper_over_can_commands_motion_streams_and_errors(can_sim: tuple[SimThread, str]) -> None:
    _, url = can_sim
    with Gripper(url, timeout=2) as g:
        assert g.info().serial_number >= 0
        data = bytes(range(200))  # 208-byte request, 210-byte reply: 27 CAN frames each way
        assert g.loop(data) == data
        g.home()  # E_CMD_PENDING, then the final frame
        g.move(40, 200)
        assert g.width() == pytest.approx(40, abs=0.5)
        m = g.move(10, 50, wait=False)
        assert not m.done()
        m.wait(5)
        g.set_soft_limits(5, 60)
        with pytest.raises(RangeError):  # beyond the soft limits: an error reply, decoded as on TCP
            g.move(80, 50)
        g.clear_soft_limits()
        with g.subscribe("width", 0.01) as s:
            g.move(30, 200, wait=False)
            samples = [s.get(2) for _ in range(5)]
        assert all(x.command == Command.GET_OPENING_WIDTH for x in samples)
        assert g.gripper_state() in (GripperState.IDLE, GripperState.POSITIONING)
        assert g.request(0x06, b"abc").params == b"abc"
    assert not g.connected


def test_async_gripper_over_can(can_sim: tuple[SimThread, str]) -> None:
    _, url = can_sim

    async def main() -> None:
        async with AsyncGripper(url, timeout=2) as g:
            data = bytes(range(100))
            assert await g.loop(data) == data
            await g.home()
            await g.move(40, 200)
            state = await g.state()  # 6 pipelined requests, their replies interleave on one identifier
            assert state.width == pytest.approx(40, abs=0.5)
            async with await g.subscribe("force", 0.01) as s:
                assert (await s.get(2)).command == Command.GET_FORCE
            await g.set_soft_limits(5, 60)
            with pytest.raises(RangeError):
                await g.move(80, 50)
            await g.clear_soft_limits()

    asyncio.run(main())


def test_identifiers_are_configurable_on_sim_and_driver(sim_factory: Callable[..., SimThread]) -> None:
    ch = channel()
    sim_factory(tcp_port=None, udp_port=None, can_channel=ch, can_rx_id=0x300, can_tx_id=0x301)
    with Gripper(f"can://{ch}?interface=virtual&request_id=0x300&reply_id=0x301", timeout=2) as g:
        assert g.loop(b"ids") == b"ids"
    with Gripper(f"can://{ch}?interface=virtual", timeout=0.3) as g, pytest.raises(TimeoutError):
        g.width()  # the default identifiers reach nobody


# -- lost fragments and foreign traffic --------------------------------------------------------------


class _Dropper:
    """Wraps a python-can bus: drops the ``n``-th CAN frame sent from now on (fault injection)."""

    def __init__(self, bus: Any, n: int) -> None:
        self.bus, self.n, self.dropped = bus, n, 0
        self._send = bus.send
        bus.send = self.send

    def send(self, msg: Any, timeout: float | None = None) -> None:
        self.n -= 1
        if self.n == 0:
            self.dropped += 1
            return
        self._send(msg, timeout)


def test_a_lost_request_fragment_fails_that_call_only(can_sim: tuple[SimThread, str]) -> None:
    _, url = can_sim
    with Gripper(url, timeout=0.5) as g:
        assert g.loop(b"before") == b"before"
        drop = _Dropper(g._transport.bus, 2)  # type: ignore[union-attr]
        with pytest.raises(WsgError):  # the device waits for bytes that never come: no reply in time
            g.loop(bytes(40))
        assert drop.dropped == 1
        # the next request's bytes complete the truncated frame, which fails its CRC (the device answers
        # E_CHECKSUM_ERROR, absorbed by the timed-out call's ghost); the parser resynchronises on the
        # next preamble inside it, so this call is answered
        assert g.info().serial_number >= 0
        assert g.loop(b"after") == b"after"
        assert g.info().serial_number == g.info().serial_number


def test_a_lost_reply_fragment_fails_that_call_only(can_sim: tuple[SimThread, str]) -> None:
    st, url = can_sim
    with Gripper(url, timeout=0.5) as g:
        assert g.loop(b"before") == b"before"
        drop = _Dropper(st.g.can._bus, 2)
        with pytest.raises((BadChecksumReply, TimeoutError)):
            g.loop(bytes(40))  # 50-byte reply, its second CAN frame lost
        assert drop.dropped == 1
        assert g.loop(b"after") == b"after"
        assert g.width() >= 0


def test_a_bus_flooded_with_foreign_identifiers_is_ignored(can_sim: tuple[SimThread, str]) -> None:
    st, url = can_sim
    ch = url.split("://")[1].split("?")[0]
    flooder = can.Bus(interface="virtual", channel=ch)
    stop = threading.Event()
    sent = [0]

    def flood() -> None:
        _flood(flooder, stop, sent, remote_id=0x01)  # remote frames on the sim's request identifier

    with Gripper(url, timeout=2) as g:
        quiet = _rate(g)
        t = threading.Thread(target=flood, daemon=True)
        t.start()
        try:
            time.sleep(0.2)
            for _ in range(50):
                assert g.loop(b"flood") == b"flood"
            flooded = _rate(g)
        finally:
            stop.set()
            t.join(5)
            flooder.shutdown()
        assert g._parser.buffered == 0  # nothing foreign reached the reassembly
        assert g.loop(b"still") == b"still"
    assert sent[0] > 300
    # the remote frames on the request identifier pass the acceptance filter and are dropped per frame
    assert st.g.can.foreign > 0
    print(f"round trips/s quiet {quiet:.0f}, flooded {flooded:.0f}")
    assert flooded > quiet / 50, (quiet, flooded)  # generous: 2 shared cores, one thread floods flat out


def _flood(bus: Any, stop: threading.Event, sent: list[int], remote_id: int) -> None:
    """Flood ``bus`` until ``stop``: ~4,000 frames/s, as a saturated 500 kbit/s bus (an 8-byte frame is
    ~125 bits on the wire). The virtual bus has no bit rate, so the pace is set here, in bursts of 39
    every 10 ms: foreign identifiers carrying a preamble, remote frames on ``remote_id``, and extended
    frames that look like a request. ``sent[0]`` counts the frames."""
    i = 0
    next_burst = time.monotonic()
    while not stop.is_set():
        for _ in range(13):
            i += 1
            bus.send(can.Message(arbitration_id=0x100 + i % 0x600, data=b"\xaa\xaa\xaa" + bytes(5),
                                 is_extended_id=False))
            bus.send(can.Message(arbitration_id=remote_id, is_remote_frame=True, is_extended_id=False))
            bus.send(can.Message(arbitration_id=0x02, data=b"\xaa\xaa\xaa\x50\x00\x00", is_extended_id=True))
            sent[0] += 3
        next_burst += 0.01
        time.sleep(max(0.0, next_burst - time.monotonic()))


def _rate(g: Gripper, n: int = 30) -> float:
    t0 = time.perf_counter()
    for _ in range(n):
        g.gripper_state()
    return n / (time.perf_counter() - t0)


# -- AsyncGripper: the same faults (issue 17) ---------------------------------------------------------


def test_async_a_wrong_identifier_times_out_and_the_call_says_so(sim_factory: Callable[..., SimThread]) -> None:
    """No reply on the reply identifier: the call ends with TimeoutError after ``timeout``, not later."""
    ch = channel()
    sim_factory(tcp_port=None, udp_port=None, can_channel=ch, can_rx_id=0x300, can_tx_id=0x301)

    async def main() -> None:
        async with AsyncGripper(f"can://{ch}?interface=virtual", timeout=0.3) as g:
            t0 = time.monotonic()
            with pytest.raises(TimeoutError):
                await g.width()           # the default identifiers reach nobody
            assert time.monotonic() - t0 < 5     # bounded (0.3 s; generous for a loaded box)
        async with AsyncGripper(f"can://{ch}?interface=virtual&request_id=0x300&reply_id=0x301", timeout=2) as g:
            assert await g.loop(b"ids") == b"ids"

    asyncio.run(main())


def test_async_a_lost_request_fragment_fails_that_call_only(can_sim: tuple[SimThread, str]) -> None:
    """000 §1.2.1: the device cannot complete (or checks the CRC of) a frame missing a fragment; the
    async call times out and the next calls on the same connection are answered."""
    _, url = can_sim

    async def main() -> None:
        async with AsyncGripper(url, timeout=0.5) as g:
            assert await g.loop(b"before") == b"before"
            drop = _Dropper(g._transport.bus, 2)  # type: ignore[union-attr]
            with pytest.raises(WsgError):
                await g.loop(bytes(40))       # 46-byte request, its second CAN frame lost
            assert drop.dropped == 1
            info = await g.info()             # completes the truncated frame (CRC error), then resyncs
            assert info.serial_number >= 0
            assert await g.loop(b"after") == b"after"

    asyncio.run(main())


def test_async_a_lost_reply_fragment_fails_that_call_only(can_sim: tuple[SimThread, str]) -> None:
    """A reply missing a fragment fails its CRC or never completes: that call raises, the next works."""
    st, url = can_sim

    async def main() -> None:
        async with AsyncGripper(url, timeout=0.5) as g:
            assert await g.loop(b"before") == b"before"
            drop = _Dropper(st.g.can._bus, 2)
            with pytest.raises((BadChecksumReply, TimeoutError)):
                await g.loop(bytes(40))       # 50-byte reply, its second CAN frame lost
            assert drop.dropped == 1
            assert await g.loop(b"after") == b"after"
            assert await g.width() >= 0

    asyncio.run(main())


def test_async_a_bus_flooded_with_foreign_identifiers_is_ignored(can_sim: tuple[SimThread, str]) -> None:
    """Foreign identifiers, remote frames and extended frames on a busy bus never reach the parser."""
    _, url = can_sim
    ch = url.split("://")[1].split("?")[0]
    flooder = can.Bus(interface="virtual", channel=ch)
    stop = threading.Event()
    sent = [0]

    def flood() -> None:
        _flood(flooder, stop, sent, remote_id=0x02)  # remote frames on the driver's reply identifier

    async def main() -> None:
        async with AsyncGripper(url, timeout=2) as g:
            t = threading.Thread(target=flood, daemon=True)
            t.start()
            try:
                await asyncio.sleep(0.2)
                for _ in range(50):
                    assert await g.loop(b"flood") == b"flood"
                await g.home()
                assert await g.gripper_state() in (GripperState.IDLE, GripperState.POSITIONING)
            finally:
                stop.set()
                await asyncio.get_running_loop().run_in_executor(None, t.join, 5)
                flooder.shutdown()
            assert g._parser.buffered == 0      # nothing foreign reached the reassembly
            transport: Any = g._transport
            assert transport.foreign > 0        # the remote frames on the reply identifier: dropped per frame
            assert await g.loop(b"still") == b"still"

    asyncio.run(main())
    assert sent[0] > 300


# -- across processes on vcan ------------------------------------------------------------------------


def _vcan() -> str | None:
    """The name of an up vcan interface, or None."""
    try:
        out = subprocess.run(["ip", "-o", "link", "show", "type", "vcan"], capture_output=True, text=True,
                             timeout=5).stdout
    except (OSError, subprocess.SubprocessError):
        return None
    for line in out.splitlines():
        name = line.split(":")[1].strip().split("@")[0]
        if "UP" in line.split("<")[1].split(">")[0]:
            return name
    return None


VCAN = _vcan()
VCAN_REASON = ("no vcan interface is up on this machine (kernel module vcan "
               f"{'loaded' if Path('/sys/module/vcan').exists() else 'not loaded'}); create one as root: "
               "`ip link add vcan0 type vcan && ip link set vcan0 up`")


@pytest.mark.skipif(VCAN is None, reason=VCAN_REASON)
def test_driver_and_sim_in_separate_processes_over_vcan(tmp_path: Path) -> None:
    assert VCAN is not None
    wsg = Path(sys.executable).with_name("wsg")
    sim = subprocess.Popen([str(wsg), "sim", "--tcp-port", "off", "--udp-port", "off", "--serial", "off",
                            "--web-port", "off", "--can", VCAN, "--can-interface", "socketcan"],
                           stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        assert sim.stdout is not None
        deadline = time.monotonic() + 15
        while time.monotonic() < deadline and "CAN" not in sim.stdout.readline():
            pass
        with Gripper(f"can://{VCAN}?interface=socketcan", timeout=2) as g:
            assert g.loop(bytes(range(100))) == bytes(range(100))
            g.home()
            assert g.system_state() is not None
    finally:
        sim.terminate()
        sim.wait(10)


def test_the_wsg_cli_takes_a_can_url(can_sim: tuple[SimThread, str]) -> None:
    from click.testing import CliRunner

    from pywsg.cli.main import cli

    _, url = can_sim  # the virtual bus lives in this process: the CLI runs in it too
    runner = CliRunner()
    r = runner.invoke(cli, ["--url", url, "home", "--json"])
    assert r.exit_code == 0, r.output
    r = runner.invoke(cli, ["--url", url, "width", "--json"])
    assert r.exit_code == 0, r.output
    assert "width" in r.output
    r = runner.invoke(cli, ["--url", url + "&request_id=0x10&reply_id=0x11", "width", "--timeout", "0.3"])
    assert r.exit_code != 0 and "no reply" in r.output.lower(), r.output
