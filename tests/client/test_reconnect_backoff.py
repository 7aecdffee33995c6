"""Issue 33 item 15: ``reconnect=True`` against a gripper that drops every connection 0.3 s after
accepting it. Each unannounced close raises FAST STOP on a WSG (000 §1.4.2), so the driver must not
reconnect forever at the first delay: a connection that dies soon after it was made continues the
back-off (the delay doubles, the attempt counts), and the driver gives up after the attempts the
user set. The gripper is the real virtual one, its network fault ``reset timeout=0.3`` plays the drop."""

from __future__ import annotations

import threading
import time

import pytest

from pywsg import AsyncGripper, Gripper, ReconnectPolicy
from pywsg.client.reconnect import Backoff
from pywsg.device import ManualClock
from pywsg.errors import ConnectionLostError
from pywsg.protocol import SystemFlag
from pywsg.testing import SimThread

ATTEMPTS = 3
POLICY = ReconnectPolicy(attempts=ATTEMPTS, delay=0.05, max_delay=1.0)  # stable_after: the default 5 s
DROP_AFTER = 0.3  # s: the gripper resets every connection this long after accepting it


def test_backoff_continues_after_a_short_connection_and_restarts_after_a_stable_one() -> None:
    clock = ManualClock(100.0)
    b = Backoff(ReconnectPolicy(attempts=3, delay=0.2, max_delay=0.5, stable_after=5.0), clock)
    b.connected()
    clock.advance(0.3)
    b.lost()  # short-lived: the schedule goes on where it stood
    assert b.next_delay() == 0.2
    b.connected()
    clock.advance(0.3)
    b.lost()
    assert b.next_delay() == 0.4
    b.connected()
    clock.advance(0.3)
    b.lost()
    assert b.next_delay() == 0.5  # capped at max_delay
    b.connected()
    clock.advance(0.3)
    b.lost()
    assert b.next_delay() is None and b.gave_up  # 3 attempts used: give up
    b.connected()  # the user connected again: a full budget
    clock.advance(6.0)
    b.lost()  # after a stable connection the schedule restarts
    assert b.next_delay() == 0.2 and not b.gave_up


def _gaps(made: list[float], lost: list[float]) -> list[float]:
    """s from each loss to the next connection."""
    return [m - lo for lo, m in zip(lost, made[1:], strict=False)]


@pytest.mark.realtime
def test_blocking_gripper_backs_off_and_gives_up_on_a_gripper_that_drops_every_connection(
        wsg_sim: SimThread) -> None:
    made: list[float] = []
    lost: list[float] = []
    gave_up = threading.Event()
    with Gripper(wsg_sim.url, reconnect=POLICY, on_reconnect=lambda f: made.append(time.monotonic()),
                 on_connection_lost=lambda e: lost.append(time.monotonic())) as g:
        made.append(time.monotonic())
        wsg_sim.world.net("reset", timeout=DROP_AFTER)
        g.reconnect()  # the current connection falls under the fault too
        made[:] = [time.monotonic()]
        stream = g.subscribe("system_state", period=0.05)  # its reader reconnects in the background

        def watch() -> None:
            for _ in stream:  # ends when the driver gives up
                pass
            gave_up.set()

        threading.Thread(target=watch, daemon=True).start()
        # today's driver reconnects forever: 36 times in 20 s
        assert gave_up.wait(20), f"still reconnecting after {len(made) - 1} reconnections"
        assert len(made) - 1 == ATTEMPTS and len(lost) == ATTEMPTS + 1
        assert not g.connected
        t0 = time.monotonic()
        with pytest.raises(ConnectionLostError):  # given up: a call fails at once, no new cycle
            g.temperature()
        assert len(made) - 1 == ATTEMPTS
        gaps = _gaps(made, lost)
        assert gaps[-1] > gaps[0], gaps  # the back-off grew: 0.05, 0.1, 0.2 s
        assert time.monotonic() - t0 < POLICY.delay * 2 ** ATTEMPTS  # failed without a new back-off
        wsg_sim.world.net("reset", on=False)
        flags = g.reconnect()  # the user may try again: a full budget
        assert SystemFlag.SF_FAST_STOP in flags  # each drop raised FAST STOP; reported, not acknowledged


@pytest.mark.realtime
async def test_async_gripper_backs_off_and_gives_up_on_a_gripper_that_drops_every_connection(
        wsg_sim: SimThread) -> None:
    made: list[float] = []
    lost: list[float] = []
    g = AsyncGripper(wsg_sim.url, reconnect=POLICY, on_reconnect=lambda f: made.append(time.monotonic()),
                     on_connection_lost=lambda e: lost.append(time.monotonic()))
    wsg_sim.world.net("reset", timeout=DROP_AFTER)
    await g.connect()
    made.append(time.monotonic())
    stream = await g.subscribe("system_state", period=0.05)
    try:
        async for _ in stream:  # ends when the driver gives up
            if len(made) > 3 * ATTEMPTS:  # today's driver: every 0.55 s, forever
                break
        assert len(made) - 1 == ATTEMPTS and len(lost) == ATTEMPTS + 1
        assert not g.connected
        with pytest.raises(ConnectionLostError):
            await g.temperature()
        gaps = _gaps(made, lost)
        assert gaps[-1] > gaps[0], gaps
        wsg_sim.world.net("reset", on=False)
        assert SystemFlag.SF_FAST_STOP in await g.reconnect()
    finally:
        await g.close()
