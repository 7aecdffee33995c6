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
