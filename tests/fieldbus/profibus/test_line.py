"""The slave on a serial *device* path (the code path of a USB RS-485 adapter), here the far side of
a pty opened through pyserial: 8E1 with parity checking on, min TSDR honoured, bad input unanswered."""

from __future__ import annotations

import asyncio
import contextlib
import os
import termios
import time
import tty
from collections.abc import AsyncIterator

import pytest

from pywsg.device import ManualClock, VirtualGripper
from pywsg.fieldbus.controller import FieldbusController
from pywsg.fieldbus.profibus import fdl
from pywsg.fieldbus.profibus.line import ProfibusAdapter

M = 2


@pytest.fixture
async def line() -> AsyncIterator[tuple[ProfibusAdapter, int]]:
    master_fd, slave_fd = os.openpty()
    tty.setraw(master_fd)
    path = os.ttyname(slave_fd)
    controller = FieldbusController(VirtualGripper("wsg50", clock=ManualClock()))
    ad = await ProfibusAdapter(controller, path, address=7, baudrate=9600).start()
    os.set_blocking(master_fd, False)
    try:
        yield ad, master_fd
    finally:
        await ad.close()
        controller.close()
        os.close(master_fd)
        os.close(slave_fd)


async def _ask(fd: int, request: bytes, timeout: float = 5.0) -> tuple[bytes, float]:
    """Write ``request``; (the response, seconds until its first byte). Repeated after 0.3 s without
    an answer, as a DP master does after its slot time: on a serial device the slave drops an answer
    it could not start within MaxTsdr (a loaded host)."""
    for _ in range(int(timeout / 0.3)):
        with contextlib.suppress(AssertionError):
            return await _ask_once(fd, request, 0.3)
    return await _ask_once(fd, request, timeout)


async def _ask_once(fd: int, request: bytes, timeout: float) -> tuple[bytes, float]:
    os.write(fd, request)
    t0 = time.monotonic()
    deadline = t0 + timeout
    data = b""
    first = 0.0
    while time.monotonic() < deadline:
        try:
            chunk = os.read(fd, 256)
        except BlockingIOError:
            chunk = b""
        if chunk:
            first = first or time.monotonic() - t0
            data += chunk
            if data == fdl.SHORT_ACK or (len(data) >= 6 and data[-1] == fdl.ED):
                return data, first
        await asyncio.sleep(0.001)
    raise AssertionError(f"no response to {request.hex(' ')} within {timeout} s (got {data.hex(' ')})")


async def test_a_device_path_is_opened_8e1_with_parity_checked(line: tuple[ProfibusAdapter, int]) -> None:
    ad, _ = line
    iflag = termios.tcgetattr(ad._fd)[0]
    assert iflag & termios.INPCK and iflag & termios.IGNPAR          # parity errors dropped
    # Even parity asked for; a pty's kernel driver clears PARENB itself (CS8, no parity), a UART keeps it.
    assert ad._line.serial.parity == "E" and ad._line.serial.bytesize == 8 and ad._line.serial.stopbits == 1
    assert ad.bus_state()["Bitrate"] == "9.6 kbit/s"                  # a real port: not "nominal"


async def test_min_tsdr_from_set_prm_delays_the_response(line: tuple[ProfibusAdapter, int]) -> None:
    """Set_Prm min TSDR 250 bit times at 9600 bit/s: no response starts sooner than 26 ms."""
    _, fd = line
    prm = bytes((0x80, 1, 1, 250, 0x55, 0x55, 0))
    resp, _ = await _ask(fd, fdl.encode(7, M, 0x5D, prm, dsap=61, ssap=62))
    assert resp == fdl.SHORT_ACK
    resp, first = await _ask(fd, fdl.encode(7, M, 0x7D, b"", dsap=60, ssap=62))
    assert resp[0] == fdl.SD2 and first >= 250 / 9600 * 0.95


async def test_bad_fcs_on_the_device_path_gets_no_answer(line: tuple[ProfibusAdapter, int]) -> None:
    ad, fd = line
    good = fdl.encode(7, M, 0x49)
    os.write(fd, good[:-2] + bytes([good[-2] ^ 1]) + good[-1:])
    await asyncio.sleep(0.05)
    with pytest.raises(BlockingIOError):
        os.read(fd, 64)
    assert ad.line_errors == 1
    resp, _ = await _ask(fd, good)
    assert resp == fdl.encode(M, 7, fdl.RES_OK)


async def test_a_port_that_goes_away_is_reported_once_not_spun_on() -> None:
    """The adapter unplugged (here: the other side of the pty closed, reads fail with EIO): the slave
    stops reading, the Bus State says Offline and why, and the loop stays free."""
    master_fd, slave_fd = os.openpty()
    path = os.ttyname(slave_fd)
    controller = FieldbusController(VirtualGripper("wsg50", clock=ManualClock()))
    ad = await ProfibusAdapter(controller, path, address=7, baudrate=9600).start()
    try:
        os.close(slave_fd)
        os.close(master_fd)
        deadline = time.monotonic() + 5
        while ad.failure is None and time.monotonic() < deadline:
            await asyncio.sleep(0.01)
        assert ad.failure is not None, "the lost port was not noticed"
        assert ad.bus_state()["Interface state"].startswith("Offline: " + path)
        t0 = time.process_time()
        await asyncio.sleep(0.2)
        assert time.process_time() - t0 < 0.15           # no busy loop on a dead descriptor
    finally:
        await ad.close()
        controller.close()
