"""``Gripper(url, reconnect=True, on_reconnect=…)``: the callbacks are constructor arguments too
(they were attributes only, and the keyword raised TypeError). Real virtual gripper over TCP."""

from __future__ import annotations

from typing import Any

from pywsg import AsyncGripper, Gripper
from pywsg.protocol import SystemFlag


def test_blocking_gripper_takes_on_reconnect_and_calls_it(wsg_sim: Any) -> None:
    seen: list[SystemFlag] = []
    lost: list[BaseException | None] = []
    with Gripper(wsg_sim.url, reconnect=True, on_reconnect=seen.append, on_connection_lost=lost.append) as g:
        assert g.on_connection_lost == lost.append
        flags = g.reconnect()  # 000 §1.4.2: announced disconnect (07h), then a new session
    assert seen == [flags]
    assert isinstance(flags, SystemFlag) and not flags & SystemFlag.SF_FAST_STOP


async def test_async_gripper_takes_on_reconnect_and_calls_it(wsg_sim: Any) -> None:
    seen: list[SystemFlag] = []
    async with AsyncGripper(wsg_sim.url, reconnect=True, on_reconnect=seen.append) as g:
        flags = await g.reconnect()
    assert seen == [flags]


async def test_async_close_then_a_new_connection_at_once_is_not_refused(wsg_sim: Any) -> None:
    """Issue 38: asyncio closes a socket one loop turn after ``transport.close()``; on Python 3.12 and
    3.13 a connection made right after ``close()`` (or inside ``reconnect()``) reached the gripper before
    the old one's FIN, and the gripper, which serves one TCP client at a time, refused it
    (E_ACCESS_DENIED). ``close()`` now returns once the socket is closed."""
    for _ in range(5):
        g = await AsyncGripper.open(wsg_sim.url)
        assert await g.loop(b"first") == b"first"
        await g.close()
        g = await AsyncGripper.open(wsg_sim.url)
        assert await g.loop(b"next") == b"next"  # not E_ACCESS_DENIED
        await g.close()
