"""The line's timing, on a socat pty pair (a real port's code path) and on both event loops the sim
runs on: answers start no earlier than min TSDR (Set_Prm), telegrams are framed by idle time, and
the watchdog is enforced when Set_Prm shrinks it (IEC 61158-4-3 / -6-3, the DP-V0 slave)."""

from __future__ import annotations

import asyncio
import os
import time
from collections.abc import Callable, Iterator

import pytest

from pywsg.fieldbus.profibus import fdl
from pywsg.fieldbus.profibus.dp import DpState
from pywsg.protocol import SystemFlag

from .lines import MASTER, ask, connect, data_exchange, loop_factories, master_end, silent, slave_on, socat_pair

pytestmark = pytest.mark.realtime
LOOPS = loop_factories()
FDL_STATUS = fdl.encode(7, MASTER, 0x49)


@pytest.fixture(scope="module")
def line(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[str, str]]:
    with socat_pair(tmp_path_factory.mktemp("socat")) as pair:
        yield pair


@pytest.mark.parametrize("loop", sorted(LOOPS))
@pytest.mark.parametrize(("rate", "min_tsdr", "requests"), [(45450, 20, 50), (9600, 60, 10)])
def test_no_answer_starts_before_min_tsdr(line: tuple[str, str], loop: str, rate: int, min_tsdr: int,
                                          requests: int) -> None:
    """Set_Prm min TSDR 20 bit times at 45.45 kbit/s (0.44 ms: under uvloop's 1 ms timer grain) and 60
    at 9.6 kbit/s (6.25 ms: an event-loop timer and then a precise wait): every answer's first byte
    comes after it, measured by the master from just before its write."""
    slave_path, master_path = line
    with slave_on(slave_path, LOOPS[loop], baudrate=rate) as (ad, _), master_end(master_path) as fd:
        connect(fd, min_tsdr=min_tsdr)
        times = []
        for i in range(requests):
            answer, first = ask(fd, data_exchange(i % 2), 0.3, retries=20)
            assert answer[:1] in (bytes([fdl.SD2]), bytes([fdl.SD1])), (
                answer, ad.line_errors, ad.late_responses, ad.parser.dropped)
            times.append(first)
        early = [t for t in times if t < min_tsdr / rate]
        assert early == [], f"{len(early)} of {requests} answers before {min_tsdr / rate * 1e3:.2f} ms"
        assert ad.slave.stats.data_exchanges + ad.slave.stats.refused >= requests - ad.late_responses


def test_an_answer_that_cannot_start_within_max_tsdr_is_not_sent(line: tuple[str, str]) -> None:
    """The master has given up on an answer later than MaxTsdr: the slave drops it (counted) instead
    of putting it on a line where it would collide with the master's repeat."""
    slave_path, master_path = line
    with slave_on(slave_path, asyncio.new_event_loop) as (ad, lt), master_end(master_path) as fd:
        lt.call(lambda: ad._send_at(fdl.SHORT_ACK, time.monotonic(), time.monotonic() - 0.001))
        assert ad.late_responses == 1 and silent(fd, 0.05)
        lt.call(lambda: ad._send_at(fdl.SHORT_ACK, time.monotonic(), time.monotonic() + 1))
        assert not silent(fd, 5.0) and os.read(fd, 8) == fdl.SHORT_ACK


@pytest.mark.parametrize("loop", sorted(LOOPS))
def test_a_telegram_cut_off_by_an_idle_line_does_not_swallow_the_next(line: tuple[str, str], loop: str) -> None:
    """An SD2 header claiming 249 bytes, cut off; after 50 ms of silence (far over 33 bit times) the
    next request is answered at once, not taken as the rest of the cut-off telegram."""
    slave_path, master_path = line
    with slave_on(slave_path, LOOPS[loop]) as (ad, _), master_end(master_path) as fd:
        os.write(fd, bytes([0x68, 249, 249, 0x68, 7, MASTER, 0x6D, 60, 62]))
        assert silent(fd, 0.05)
        answer, _ = ask(fd, FDL_STATUS, 0.3, retries=20)
        assert answer == fdl.encode(MASTER, 7, fdl.RES_OK)
        assert ad.line_errors == 1


def test_a_telegram_inside_a_frame_with_a_corrupted_length_byte_gets_no_answer(line: tuple[str, str]) -> None:
    """A frame to station 9 whose data unit holds a whole FDL status request to station 7, sent with
    its LE byte corrupted: station 7 does not answer the request inside; after an idle line it answers
    the real one."""
    slave_path, master_path = line
    frame = bytearray(fdl.encode(9, MASTER, 0x7D, b"\x00" + FDL_STATUS + b"\x00", dsap=60, ssap=62))
    frame[1] ^= 0x01
    with slave_on(slave_path, asyncio.new_event_loop) as (ad, _), master_end(master_path) as fd:
        answer, _ = ask(fd, bytes(frame), timeout=0.2)
        assert answer == b"" and ad.line_errors == 1
        answer, _ = ask(fd, FDL_STATUS, 0.3, retries=20)
        assert answer == fdl.encode(MASTER, 7, fdl.RES_OK)


def _wait(check: Callable[[], bool], timeout: float) -> float:
    """Seconds until ``check()`` (polled every 5 ms); ``timeout`` when it never held."""
    t0 = time.monotonic()
    while time.monotonic() - t0 < timeout:
        if check():
            return time.monotonic() - t0
        time.sleep(0.005)
    return timeout


@pytest.mark.parametrize("loop", sorted(LOOPS))
def test_a_shrunk_watchdog_expires_at_its_new_time(line: tuple[str, str], loop: str) -> None:
    """Set_Prm with a 5 s watchdog, then a Set_Prm with 100 ms, then silence: the slave leaves Data_Exch
    (FAST STOP, zero outputs, Wait_Prm) long before the first watchdog's 5 s; the gripper is fail-safe."""
    slave_path, master_path = line
    with slave_on(slave_path, LOOPS[loop]) as (ad, lt), master_end(master_path) as fd:
        connect(fd, watchdog=(250, 2))
        assert ad.slave.watchdog_s == pytest.approx(5.0)
        connect(fd, watchdog=(10, 1))
        spent = _wait(lambda: lt.call(lambda: ad.slave.state) is DpState.WAIT_PRM, 5.0)
        assert spent < 2.5, f"still in Data_Exch {spent:.2f} s after a 100 ms watchdog (the old one was 5 s)"
        assert ad.slave.stats.watchdog_expiries == 1
        # the FAST STOP reaches the input image at the gripper's next poll, a moment after the state change
        def fast_stop() -> bool:
            flags = lt.call(lambda: ad.controller.input_bytes())
            return bool(int.from_bytes(flags[2:6], "little") & SystemFlag.SF_FAST_STOP)

        assert _wait(fast_stop, 10.0) < 10.0, "no FAST STOP in the input image after the watchdog expired"
        assert "watchdog expired" in ad.bus_state()["Interface state"]


def test_a_late_telegram_does_not_revive_an_expired_slave(line: tuple[str, str]) -> None:
    """The master's next Data_Exchange comes after the watchdog: refused (RS), not answered with data."""
    slave_path, master_path = line
    with slave_on(slave_path, asyncio.new_event_loop) as (ad, _), master_end(master_path) as fd:
        connect(fd, watchdog=(5, 1))
        time.sleep(0.2)
        answer, _ = ask(fd, data_exchange(0), 0.3, retries=20)   # FCB toggled after Chk_Cfg's: a new request
        assert answer == fdl.encode(MASTER, 7, fdl.RES_RS)
        assert ad.slave.state is DpState.WAIT_PRM

