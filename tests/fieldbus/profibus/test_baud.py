"""Baud-rate detection (003 §6: "Profibus Bitrate (automatically detected)"): the slave listens at each
declared rate in turn, locks to the master's, shows it in the Bus State, and searches again when the
line stays silent."""

from __future__ import annotations

import asyncio
import fcntl
import os
import struct
import threading
import time
import tty

import pytest

from pywsg.fieldbus.profibus import fdl
from pywsg.fieldbus.profibus.baud import BaudSearch
from pywsg.fieldbus.profibus.gsd import facts
from pywsg.fieldbus.profibus.line import ProfibusAdapter

from .lines import MASTER, slave_on

TCGETS2 = 0x802C542A   # Linux ioctl: struct termios2, its c_ospeed at byte 40


def test_the_search_runs_from_the_highest_rate_down_and_wraps() -> None:
    s = BaudSearch([9600, 1_500_000, 45450], now=0.0, dwell_s=0.25)
    assert s.rate == 1_500_000 and not s.locked
    assert s.tick(0.2) is None
    assert s.tick(0.25) == 45450 and s.tick(0.5) == 9600 and s.tick(0.75) == 1_500_000


def test_a_good_telegram_locks_and_silence_starts_the_search_again() -> None:
    s = BaudSearch([9600, 19200, 45450], now=0.0, dwell_s=0.25, hold_s=3.0)
    s.tick(0.25)
    s.heard(0.3)
    assert not s.locked                               # one telegram could be a straggler
    s.heard(0.31)
    assert s.locked and s.rate == 19200
    assert s.tick(3.2) is None                       # 2.9 s of silence: still locked
    assert s.tick(3.2, hold_s=0.5) == 45450          # with a 0.5 s watchdog: lost, from the top
    assert not s.locked and s.searches == 2


def _ospeed(master_fd: int) -> int:
    """The baud rate the slave set on its side of the pty (read from the master side)."""
    buf = bytearray(44)
    fcntl.ioctl(master_fd, TCGETS2, buf)
    return int(struct.unpack_from("I", buf, 40)[0])


class RateLine(threading.Thread):
    """A DP master at ``rate`` on the master side of a pty: while the slave listens at another rate
    it reads what a UART at the wrong rate reads (here: bytes that form no telegram); at the right
    rate, the master's FDL status requests to station 7, every 5 ms."""

    def __init__(self, fd: int, rate: int) -> None:
        super().__init__(daemon=True)
        self.fd, self.rate = fd, rate
        self.answers = b""
        self.stop = threading.Event()

    def run(self) -> None:
        request = fdl.encode(7, MASTER, 0x49)
        while not self.stop.is_set():
            right = _ospeed(self.fd) == self.rate
            os.write(self.fd, request if right else bytes([0xFF, 0x00, 0xFE]) * 2)
            time.sleep(0.005)
            try:
                self.answers += os.read(self.fd, 256)
            except BlockingIOError:
                pass


@pytest.mark.parametrize("rate", [1_500_000, 93750])
def test_the_slave_locks_to_the_masters_rate_and_the_bus_state_says_so(rate: int) -> None:
    master_fd, slave_fd = os.openpty()
    tty.setraw(master_fd)
    os.set_blocking(master_fd, False)
    line = RateLine(master_fd, rate)
    try:
        with slave_on(os.ttyname(slave_fd), asyncio.new_event_loop, baudrate=None,
                      baud_dwell_s=0.05) as (ad, lt):
            assert ad.bus_state()["Bitrate"] == "searching (automatic detection)"
            line.start()
            deadline = time.monotonic() + 20
            while not (ad.search and ad.search.locked) and time.monotonic() < deadline:
                time.sleep(0.01)
            assert ad.search is not None and ad.search.locked and ad.baudrate == rate
            text = "1.5 Mbit/s" if rate == 1_500_000 else "93.75 kbit/s"
            assert lt.call(ad.bus_state)["Bitrate"] == f"{text} (automatically detected)"
            deadline = time.monotonic() + 10
            while fdl.encode(MASTER, 7, fdl.RES_OK) not in line.answers and time.monotonic() < deadline:
                time.sleep(0.01)
            assert fdl.encode(MASTER, 7, fdl.RES_OK) in line.answers     # and it answers at that rate
            assert "baudrate" not in ad.url
    finally:
        line.stop.set()
        if line.is_alive():
            line.join(5)
        os.close(master_fd)
        os.close(slave_fd)


def test_detection_on_a_pty_is_refused() -> None:
    with pytest.raises(ValueError, match="needs a serial port"):
        ProfibusAdapter(object(), "pty", baudrate=None)  # type: ignore[arg-type]
    assert max(facts().baud_rates) == 1_500_000
