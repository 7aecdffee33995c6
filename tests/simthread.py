"""A ``SimServer`` on its own event loop in a daemon thread, for tests that talk to it from blocking
code (raw sockets, the blocking driver) or from another loop (the asyncio driver)."""

from __future__ import annotations

import asyncio
import threading
from collections.abc import Callable, Coroutine, Iterator
from concurrent.futures import Future
from typing import Any, TypeVar

from pywsg.server import SimOptions, SimServer

S = TypeVar("S", bound="SimThread")


class SimThread:
    """``run(coro)`` and ``call(fn)`` execute on the server's loop (device state is touched only there)."""

    save_on_stop = True

    def __init__(self, **options: Any) -> None:
        self.options = SimOptions(**options)
        self.loop = asyncio.new_event_loop()
        self.sim = SimServer(self.options)
        self._thread = threading.Thread(target=self.loop.run_forever, daemon=True)

    def start(self: S) -> S:
        self._thread.start()
        self.run(self.sim.start())
        return self

    def run(self, coro: Coroutine[Any, Any, Any], timeout: float = 10) -> Any:
        fut: Future[Any] = asyncio.run_coroutine_threadsafe(coro, self.loop)
        return fut.result(timeout)

    def call(self, fn: Callable[[], Any], timeout: float = 10) -> Any:
        """Run ``fn()`` on the server's loop thread."""

        async def _do() -> Any:
            return fn()

        return self.run(_do(), timeout)

    def stop(self) -> None:
        try:
            self.run(self.sim.close(save=self.save_on_stop))
        finally:
            self.loop.call_soon_threadsafe(self.loop.stop)
            self._thread.join(5)
            self.loop.close()

    @property
    def g(self) -> Any:
        return self.sim.grippers[0]


def started(cls: type[S]) -> Iterator[Callable[..., S]]:
    """Body of a ``sim_factory`` fixture: ``make(**options)`` starts one; all stop at teardown."""
    running: list[S] = []

    def make(**options: Any) -> S:
        st = cls(**options).start()
        running.append(st)
        return st

    yield make
    for st in running:
        st.stop()
