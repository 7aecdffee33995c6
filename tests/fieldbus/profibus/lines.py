"""A serial line with a real port's code path for the DP slave, and a byte-level master on its far end.

``socat pty,raw,echo=0,link=A pty,raw,echo=0,link=B`` joins two ptys: the slave opens A as a serial
device (pyserial, 8E1, parity checking: the code path of a USB RS-485 adapter), the test writes and
reads B. The slave runs on an event loop of the test's choice (uvloop or stock asyncio) in a thread of
its own, so the master's clock in the test thread measures it from outside.
"""

from __future__ import annotations

import asyncio
import contextlib
import os
import select
import shutil
import subprocess
import threading
import time
import tty
from collections.abc import Callable, Coroutine, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any, TypeVar

import pytest

from pywsg.device import ManualClock, VirtualGripper
from pywsg.fieldbus.controller import FieldbusController
from pywsg.fieldbus.profibus import fdl
from pywsg.fieldbus.profibus.line import ProfibusAdapter

T = TypeVar("T")
MASTER = 2


def loop_factories() -> dict[str, Callable[[], asyncio.AbstractEventLoop]]:
    """The loops the sim runs on: stock asyncio, and uvloop (what ``[web]`` installs) when present."""
    out: dict[str, Callable[[], asyncio.AbstractEventLoop]] = {"asyncio": asyncio.new_event_loop}
    try:
        import uvloop
    except ImportError:
        return out
    out["uvloop"] = uvloop.new_event_loop
    return out


@contextmanager
def socat_pair(tmp: Path) -> Iterator[tuple[str, str]]:
    """Two linked ptys (slave end, master end); socat is stopped at exit."""
    if shutil.which("socat") is None:
        pytest.fail("socat is needed for the serial-line tests (Debian: apt-get install socat; scripts/test.sh)")
    a, b = tmp / "slave", tmp / "master"
    proc = subprocess.Popen(["socat", f"pty,raw,echo=0,link={a}", f"pty,raw,echo=0,link={b}"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 10
        while not (a.exists() and b.exists()):
            if time.monotonic() > deadline or proc.poll() is not None:
                raise AssertionError("socat did not make its pty pair")
            time.sleep(0.01)
        yield str(a), str(b)
    finally:
        proc.terminate()
        proc.wait(10)


class LoopThread:
    """An event loop running in a thread of its own."""

    def __init__(self, factory: Callable[[], asyncio.AbstractEventLoop]) -> None:
        self.loop = factory()
        self.thread = threading.Thread(target=self.loop.run_forever, name="slave-loop", daemon=True)
        self.thread.start()

    def run(self, coro: Coroutine[Any, Any, T], timeout: float = 10.0) -> T:
        return asyncio.run_coroutine_threadsafe(coro, self.loop).result(timeout)

    def call(self, fn: Callable[[], T]) -> T:
        """``fn()`` on the loop's thread (the adapter is not thread-safe)."""
        async def wrap() -> T:
            return fn()
        return self.run(wrap())

    def close(self) -> None:
        self.loop.call_soon_threadsafe(self.loop.stop)
        self.thread.join(10)
        self.loop.close()


@contextmanager
def slave_on(path: str, factory: Callable[[], asyncio.AbstractEventLoop], *, baudrate: int | None = 45450,
             **kw: Any) -> Iterator[tuple[ProfibusAdapter, LoopThread]]:
    """A DP slave (station 7, a real controller and virtual gripper) on the serial device ``path``."""
    lt = LoopThread(factory)
    controller = FieldbusController(VirtualGripper("wsg50", clock=ManualClock()))

    async def start() -> ProfibusAdapter:
        return await ProfibusAdapter(controller, path, address=7, baudrate=baudrate, **kw).start()

    ad = lt.run(start())
    try:
        yield ad, lt
    finally:
        lt.run(ad.close())
        lt.close()
        controller.close()


@contextmanager
def master_end(path: str) -> Iterator[int]:
    """The far end of the line, raw and non-blocking."""
    fd = os.open(path, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
    tty.setraw(fd)
    try:
        yield fd
    finally:
        os.close(fd)


def ask(fd: int, request: bytes, timeout: float = 3.0, *, retries: int = 0) -> tuple[bytes, float]:
    """Write ``request``; (the whole answer, seconds from just before the write to its first byte).
    ``b""`` and ``timeout`` when none comes. ``retries``: repeat the request (same FCB) that many times
    when ``timeout`` passes without an answer, as a DP master does after its slot time (a slave on a
    loaded machine drops an answer it could not start within MaxTsdr)."""
    for _ in range(retries):
        answer, first = ask(fd, request, timeout)
        if answer:
            return answer, first
        while not silent(fd, 0.05):             # a straggler is no answer to the repeat
            with contextlib.suppress(BlockingIOError):
                os.read(fd, 512)
    t0 = time.monotonic()
    os.write(fd, request)
    ready, _, _ = select.select([fd], [], [], timeout)
    first = time.monotonic() - t0
    if not ready:
        return b"", timeout
    data = b""
    parser = fdl.FdlParser()
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        try:
            chunk = os.read(fd, 512)
        except BlockingIOError:
            select.select([fd], [], [], 0.01)
            continue
        data += chunk
        if data == fdl.SHORT_ACK or any(isinstance(e, fdl.Telegram) for e in parser.feed(chunk)):
            return data, first
    return data, first


def silent(fd: int, seconds: float) -> bool:
    """True when nothing arrives on ``fd`` for ``seconds``."""
    ready, _, _ = select.select([fd], [], [], seconds)
    return not ready


def connect(fd: int, *, min_tsdr: int = 11, watchdog: tuple[int, int] | None = None) -> None:
    """Set_Prm (locked, this min TSDR, the watchdog factors or none) and Chk_Cfg: Data_Exch."""
    status = 0x80 | (0x08 if watchdog else 0)
    wd = watchdog or (1, 1)
    prm = bytes((status, *wd, min_tsdr, 0x55, 0x55, 0))
    for fc, dsap, data in ((0x5D, 61, prm), (0x7D, 62, b"\xa7\x9b")):
        answer, _ = ask(fd, fdl.encode(7, MASTER, fc, data, dsap=dsap, ssap=62), 0.3, retries=20)
        assert answer == fdl.SHORT_ACK, (dsap, answer)


def data_exchange(fcb: int) -> bytes:
    """A Data_Exchange request with zero outputs; ``fcb`` 0 or 1 (FCV set)."""
    return fdl.encode(7, MASTER, 0x5D | (0x20 if fcb else 0), bytes(8))
