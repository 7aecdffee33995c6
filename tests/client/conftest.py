"""Fixtures: the real virtual gripper served by ``SimServer`` (TCP, UDP, pty) on its own event loop
in a background thread, so both the blocking and the asyncio driver can talk to it. Motion is fast:
acceleration 5000 mm/s² (the WSG 50's maximum) and speeds up to 420 mm/s, on the real clock."""

from __future__ import annotations

import asyncio
import threading
from collections.abc import Callable, Coroutine, Iterator
from concurrent.futures import Future
from typing import Any

import pytest

from pywsg.device import Settings, VirtualGripper
from pywsg.server import SimOptions, SimServer

FAST = 400.0  # mm/s


def fast_factory(model: str, settings: Any, clock: Any) -> VirtualGripper:
    s = (settings or Settings()).updated(default_acceleration=5000.0, finger1="fmf")
    return VirtualGripper(model, settings=s, **({"clock": clock} if clock is not None else {}))


class SimThread:
    def __init__(self, **options: Any) -> None:
        opts: dict[str, Any] = {"factory": fast_factory, "tcp_port": 0, "udp_port": 0, "serial": "pty", **options}
        self.sim = SimServer(SimOptions(**opts))
        self.loop = asyncio.new_event_loop()
        self._thread = threading.Thread(target=self.loop.run_forever, daemon=True)

    def start(self) -> SimThread:
        self._thread.start()
        self.run(self.sim.start())
        return self

    def run(self, coro: Coroutine[Any, Any, Any], timeout: float = 10) -> Any:
        fut: Future[Any] = asyncio.run_coroutine_threadsafe(coro, self.loop)
        return fut.result(timeout)

    def call(self, fn: Callable[[], Any]) -> Any:
        """Run ``fn()`` on the sim's loop (device state is touched only there)."""

        async def _do() -> Any:
            return fn()

        return self.run(_do())

    def stop(self) -> None:
        try:
            self.run(self.sim.close(save=False))
        finally:
            self.loop.call_soon_threadsafe(self.loop.stop)
            self._thread.join(5)
            self.loop.close()

    @property
    def device(self) -> VirtualGripper:
        g: VirtualGripper = self.sim.grippers[0].gripper
        return g

    def url(self, kind: str) -> str:
        sg = self.sim.grippers[0]
        if kind == "tcp":
            return str(sg.tcp_url)
        if kind == "udp":  # the sim replies to the sender's port: bind any free reply port
            return f"udp://127.0.0.1:{self.sim.udp_port}?reply_port=0"
        return f"serial://{self.sim.serial_path}?baudrate=115200"


@pytest.fixture
def sim_factory() -> Iterator[Callable[..., SimThread]]:
    started: list[SimThread] = []

    def make(**options: Any) -> SimThread:
        st = SimThread(**options).start()
        started.append(st)
        return st

    yield make
    for st in started:
        st.stop()


@pytest.fixture
def sim(sim_factory: Callable[..., SimThread]) -> SimThread:
    return sim_factory()
