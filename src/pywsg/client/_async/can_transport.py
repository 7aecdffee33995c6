"""asyncio CAN transport of :class:`~pywsg.client.AsyncGripper` (``can://``; mapping in :mod:`pywsg.client.can`)."""

from __future__ import annotations

import asyncio
import threading
from typing import Any

from ..can import accepts, open_bus, send
from ..url import Endpoint
from .transport import AsyncTransport, OnData, OnLost


class CanTransport(AsyncTransport):
    """asyncio: a python-can ``Notifier`` delivers the frames on the event loop (socketcan: through
    ``add_reader``; other interfaces: a reader thread)."""

    def __init__(self, ep: Endpoint, bus: Any, on_data: OnData, on_lost: OnLost,
                 loop: asyncio.AbstractEventLoop) -> None:
        import can

        self.ep = ep
        self.bus = bus
        self.peer = str(ep)
        self.foreign = 0
        self._on_data = on_data
        self._on_lost = on_lost
        self._closed = False
        self._lock = threading.Lock()
        outer = self

        class _Listener(can.Listener):
            def on_message_received(self, msg: can.Message) -> None:
                outer._received(msg)

            def on_error(self, exc: Exception) -> None:
                outer._failed(exc)

        self._notifier = can.Notifier(bus, [_Listener()], timeout=0.05, loop=loop)

    @classmethod
    async def connect(cls, ep: Endpoint, on_data: OnData, on_lost: OnLost, timeout: float) -> CanTransport:
        loop = asyncio.get_running_loop()
        bus = await asyncio.wait_for(loop.run_in_executor(None, open_bus, ep), timeout)
        return cls(ep, bus, on_data, on_lost, loop)

    def _received(self, msg: Any) -> None:
        if self._closed:
            return
        if accepts(msg, self.ep):
            self._on_data(memoryview(msg.data))
        else:
            self.foreign += 1

    def _failed(self, exc: Exception) -> None:
        if not self._closed:
            self.close()
            self._on_lost(ConnectionResetError(f"CAN receive on {self.ep.path!r} failed: {exc}"))

    def write(self, data: bytes) -> None:
        try:
            send(self.bus, self.ep, data, 1.0)
        except ConnectionResetError as exc:
            self._failed(exc)

    def close(self) -> None:
        with self._lock:
            if self._closed:
                return
            self._closed = True
        try:
            self._notifier.stop(0.2)
        except Exception:
            pass
        try:
            self.bus.shutdown()
        except Exception:
            pass
