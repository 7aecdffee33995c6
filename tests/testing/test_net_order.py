"""Network faults never corrupt the byte stream they carry (issue 33 items 1-3).

TCP keeps the order of what it carries whatever the link does: latency, jitter, a bandwidth limit and a
slicer, in any combination, switched on and off while replies are in flight, may only delay bytes. The
sim and ``wsg proxy`` keep one ordered queue per connection and direction
(:class:`~pywsg.server.netfault.Shaper`); before, pieces due at equal times were scheduled as separate
timers and the loop's heap did not keep them in order (one 50h reply through latency + slicer came out
as ``aa aa 00 27 38 ea 00 11 ...``). Also: ``reset`` with timeout 0 resets every new connection, and a
UDP reply held back by latency goes to the client that asked.
"""

from __future__ import annotations

import asyncio
import itertools
import socket
import threading
import time
from collections.abc import Callable, Iterator

import pytest

from pywsg.protocol import ChecksumMismatch, Command, Frame, FrameParser
from pywsg.server.netfault import NetFaults, Shaper
from pywsg.testing import LoopThread, SimThread
from pywsg.testing.proxy import Proxy

# Every combination of the faults that delay without losing (garble, drop, reorder and silence lose
# bytes on purpose), each in a few shapes: jitter or none, 1-byte or 3-byte slices, a gap or none.
_SHAPES: dict[str, list[dict[str, float]]] = {
    "latency": [{"ms": 1.0}, {"ms": 1.5, "jitter": 1.0}],
    "bandwidth": [{"rate": 2_000_000}],
    "slicer": [{"size": 1}, {"size": 3}, {"size": 1, "gap": 0.02}],
}
COMBOS: list[dict[str, dict[str, float]]] = []
for _n in range(len(_SHAPES) + 1):
    for _kinds in itertools.combinations(_SHAPES, _n):
        for _params in itertools.product(*(_SHAPES[k] for k in _kinds)):
            COMBOS.append(dict(zip(_kinds, _params, strict=True)))


def _switch(apply: Callable[[str, dict[str, object]], object], combo: dict[str, dict[str, float]]) -> None:
    """Make exactly ``combo`` the faults that are on (``apply(kind, params)`` is ``NetFaults.set``)."""
    for kind in _SHAPES:
        apply(kind, {"on": True, **combo[kind]} if kind in combo else {"on": False})


def _reply(i: int) -> bytes:
    """A distinct frame per index (a LOOP reply carrying ``i``)."""
    return Frame(Command.LOOP, b"\0\0" + i.to_bytes(4, "big")).encode()


def _loops() -> list[Callable[[], asyncio.AbstractEventLoop]]:
    out: list[Callable[[], asyncio.AbstractEventLoop]] = [asyncio.new_event_loop]
    try:
        import uvloop
    except ImportError:  # pragma: no cover - the [web] extra brings it
        return out
    return [*out, uvloop.new_event_loop]


@pytest.mark.parametrize("new_loop", _loops(), ids=lambda f: f.__module__.split(".")[0])
def test_every_combination_switched_at_runtime_keeps_the_stream_whole(
        new_loop: Callable[[], asyncio.AbstractEventLoop]) -> None:
    """4,000 frames through one shaper, the faults switched every 25 frames through all combinations."""
    async def play() -> tuple[bytes, bytes, int]:
        nf = NetFaults(seed=33)
        written: list[bytes] = []
        shaper = Shaper(nf, written.append)
        sent: list[bytes] = []
        for i in range(4000):
            if i % 25 == 0:
                _switch(nf.set, COMBOS[(i // 25) % len(COMBOS)])
            frame = _reply(i)
            sent.append(frame)
            shaper.send(frame)
            if i % 3 == 0:
                await asyncio.sleep(0 if i % 2 else 0.0005)  # timers fire between sends, some due at once
        nf.clear()
        for _ in range(2000):
            if not shaper.busy:
                break
            await asyncio.sleep(0.005)
        return b"".join(sent), b"".join(written), nf.counts["overflow"]

    loop = new_loop()
    try:
        sent, written, overflow = loop.run_until_complete(play())
    finally:
        loop.close()
    assert overflow == 0
    assert len(written) == len(sent)
    first = next((i for i, (a, b) in enumerate(zip(sent, written, strict=True)) if a != b), None)
    assert first is None, f"the stream differs from byte {first} on"


def _pipelined(port: int, switch: Callable[[dict[str, dict[str, float]]], object], frames: int = 2000,
               batch: int = 20) -> tuple[int, int, list[str]]:
    """``frames`` LOOP requests (000 §3.1.1) in pipelined batches on one connection while another thread
    switches the faults through every combination; returns (good replies, bad checksums, problems)."""
    stop = threading.Event()

    def switcher() -> None:
        for combo in itertools.cycle(COMBOS):
            if stop.is_set():
                return
            switch(combo)
            time.sleep(0.002)

    th = threading.Thread(target=switcher, daemon=True)
    th.start()
    good = bad = 0
    problems: list[str] = []
    try:
        with socket.create_connection(("127.0.0.1", port), timeout=10) as s:
            parser = FrameParser(verify_checksum=True)
            n = 0
            while n < frames:
                s.sendall(b"".join(Frame(Command.LOOP, (n + k).to_bytes(4, "big")).encode() for k in range(batch)))
                want = n
                n += batch
                while want < n:
                    chunk = s.recv(65536)
                    assert chunk, "closed"
                    for ev in parser.feed(chunk):
                        if isinstance(ev, Frame):
                            if ev.payload[2:] == want.to_bytes(4, "big"):
                                good += 1
                            else:
                                problems.append(f"reply {want}: {ev.payload.hex()}")
                            want += 1
                        elif isinstance(ev, ChecksumMismatch):
                            bad += 1
                            want += 1
                        else:
                            problems.append(type(ev).__name__)
                    if len(problems) > 5:
                        return good, bad, problems
    finally:
        stop.set()
        th.join()
    return good, bad, problems


@pytest.fixture(scope="module")
def sim() -> Iterator[SimThread]:
    with SimThread(clock="manual", udp_port=0) as s:
        yield s


def test_sim_replies_stay_whole_under_every_combination_switched_at_runtime(sim: SimThread) -> None:
    try:
        good, bad, problems = _pipelined(sim.g.tcp_port, lambda c: _switch(
            lambda k, p: sim.world.net(k, **p), c))  # type: ignore[arg-type]
    finally:
        sim.world.net("clear")
    assert (bad, problems) == (0, [])
    assert good == 2000


def test_proxy_replies_stay_whole_under_every_combination_switched_at_runtime(sim: SimThread) -> None:
    loop = LoopThread("order-proxy")
    try:
        proxy = Proxy(sim.url, net=NetFaults())
        loop.run(proxy.start())
        try:
            good, bad, problems = _pipelined(proxy.port_bound, lambda c: loop.call(
                lambda: _switch(proxy.net.set, c)))
        finally:
            loop.run(proxy.close())
    finally:
        loop.close()
    assert (bad, problems) == (0, [])
    assert good == 2000


def test_proxy_latency_and_1_byte_slicer_keep_a_reply_whole(sim: SimThread) -> None:
    """The issue's reproducer: 50h replies (000 §3.5.1 Get System Information) through latency 5 ms + slicer 1."""
    loop = LoopThread("order-proxy-50h")
    nf = NetFaults()
    nf.set("latency", {"ms": 5})
    nf.set("slicer", {"size": 1})
    try:
        proxy = Proxy(sim.url, net=nf)
        loop.run(proxy.start())
        try:
            with socket.create_connection(("127.0.0.1", proxy.port_bound), timeout=10) as s:
                for _ in range(50):
                    s.sendall(Frame(Command.GET_SYSTEM_INFO).encode())
                parser, frames = FrameParser(verify_checksum=True), []
                while len(frames) < 50:
                    chunk = s.recv(4096)
                    assert chunk
                    frames += parser.feed(chunk)
        finally:
            loop.run(proxy.close())
    finally:
        loop.close()
    assert all(isinstance(f, Frame) and f.command_id == Command.GET_SYSTEM_INFO for f in frames), frames[:3]


def _refused(port: int) -> str:
    """What a new connection gets for a LOOP request: "reset", "closed" or "answered"."""
    try:
        with socket.create_connection(("127.0.0.1", port), timeout=5) as s:
            s.sendall(Frame(Command.LOOP, b"r").encode())
            data = s.recv(100)
    except (ConnectionResetError, BrokenPipeError):
        return "reset"
    return "answered" if data else "closed"


def test_reset_with_timeout_0_resets_every_new_connection(sim: SimThread) -> None:
    """docs/testing.md: reset ``timeout`` 0 is "now and at every connect"."""
    sim.world.net("reset", timeout=0)
    try:
        assert sim.world.state()["net"] == {"reset": {"timeout": 0.0}}
        assert [_refused(sim.g.tcp_port) for _ in range(3)] == ["reset"] * 3
    finally:
        sim.world.net("clear")
    assert _refused(sim.g.tcp_port) == "answered"
    loop = LoopThread("reset-0-proxy")
    try:
        nf = NetFaults()
        nf.set("reset", {"timeout": 0})
        proxy = Proxy(sim.url, net=nf)
        loop.run(proxy.start())
        try:
            assert [_refused(proxy.port_bound) for _ in range(3)] == ["reset"] * 3
        finally:
            loop.run(proxy.close())
    finally:
        loop.close()


def test_a_delayed_udp_reply_goes_to_the_client_that_asked(sim: SimThread) -> None:
    sim.world.net("latency", ms=60)
    try:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as a, \
                socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as b:
            a.settimeout(5)
            b.settimeout(5)
            addr = ("127.0.0.1", sim.g.udp_port)
            a.sendto(Frame(Command.LOOP, b"from A").encode(), addr)
            b.sendto(Frame(Command.LOOP, b"from B").encode(), addr)  # before A's reply leaves
            got_a = next(e for e in FrameParser().feed(a.recv(100)) if isinstance(e, Frame))
            got_b = next(e for e in FrameParser().feed(b.recv(100)) if isinstance(e, Frame))
    finally:
        sim.world.net("clear")
    assert (got_a.payload[2:], got_b.payload[2:]) == (b"from A", b"from B")


def test_a_stream_that_must_lose_nothing_pauses_its_source_instead() -> None:
    """``wsg proxy`` forwards whatever it read, not whole frames: over the bound it stops reading the
    gripper (``hold``) where the sim drops a whole reply (``counts["overflow"]``)."""
    from pywsg.server.netfault import MAX_PENDING

    async def flood() -> tuple[list[bool], int, int, bool]:
        nf = NetFaults()
        nf.set("bandwidth", {"rate": 1_000_000})
        holds: list[bool] = []
        written: list[bytes] = []
        shaper = Shaper(nf, written.append, hold=holds.append)
        blob = bytes(range(256)) * 4
        for _ in range(2 * MAX_PENDING // len(blob)):  # twice the bound, in 1 KiB reads
            shaper.send(blob)
        for _ in range(1000):
            if not shaper.busy:
                break
            await asyncio.sleep(0.01)
        whole = b"".join(written) == blob * (2 * MAX_PENDING // len(blob))
        return holds, nf.counts["overflow"], len(b"".join(written)), whole

    holds, overflow, n, whole = asyncio.run(flood())
    assert overflow == 0 and whole, n
    assert holds == [True, False]
