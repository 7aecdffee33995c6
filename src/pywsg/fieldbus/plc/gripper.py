"""The PLC side, blocking: :class:`FieldbusGripper`, the :class:`AsyncFieldbusGripper` on a private
event-loop thread (same methods, same units)."""

from __future__ import annotations

import asyncio
import threading
from collections.abc import Coroutine
from typing import Any, TypeVar

from ..image import CmdFlag, InputImage, OutputImage
from .async_gripper import AsyncFieldbusGripper

T = TypeVar("T")


class FieldbusGripper:
    """Blocking :class:`AsyncFieldbusGripper`: same methods, run on a private event-loop thread."""

    def __init__(self, host: str = "127.0.0.1", port: int = 502, *, model: str = "wsg50", device_id: int = 1,
                 timeout: float = 3.0) -> None:
        """``host`` is a host name for Modbus/TCP on ``port``, or a URL for any bus
        (``modbus-tcp://HOST:PORT``, ``profinet://IFACE/STATION``, ``profibus://PORT?address=N``)."""
        self._loop = asyncio.new_event_loop()
        self._thread = threading.Thread(target=self._loop.run_forever, name="fieldbus-gripper", daemon=True)
        self._thread.start()
        opening = (AsyncFieldbusGripper.open_url(host, model=model, timeout=timeout) if "://" in host else
                   AsyncFieldbusGripper.open(host, port, model=model, device_id=device_id, timeout=timeout))
        try:
            self._async = self._run(opening)
        except BaseException:
            self._stop_loop()
            raise

    def _run(self, coro: Coroutine[Any, Any, T]) -> T:
        return asyncio.run_coroutine_threadsafe(coro, self._loop).result()

    def _stop_loop(self) -> None:
        self._loop.call_soon_threadsafe(self._loop.stop)
        self._thread.join(timeout=5)
        self._loop.close()

    def close(self) -> None:
        """Close the connection and the loop thread."""
        if self._loop.is_closed():
            return
        self._run(self._async.close())
        self._stop_loop()

    def __enter__(self) -> FieldbusGripper:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    @property
    def outputs(self) -> OutputImage:
        return self._async.outputs

    def read(self) -> InputImage:
        return self._run(self._async.read())

    def write(self, image: OutputImage) -> None:
        self._run(self._async.write(image))

    def cycle(self, image: OutputImage | None = None) -> InputImage:
        return self._run(self._async.cycle(image))

    def command(self, flag: CmdFlag, **kw: Any) -> InputImage:
        return self._run(self._async.command(flag, **kw))

    def homing(self, timeout: float = 10.0) -> InputImage:
        return self._run(self._async.homing(timeout))

    def move(self, width: float, speed: float, force: float | None = None, wait: bool = True) -> InputImage:
        return self._run(self._async.move(width, speed, force, wait))

    def grip(self, width: float, speed: float, force: float, wait: bool = True) -> InputImage:
        return self._run(self._async.grip(width, speed, force, wait))

    def release(self, width: float, speed: float, wait: bool = True) -> InputImage:
        return self._run(self._async.release(width, speed, wait))

    def stop(self) -> InputImage:
        return self._run(self._async.stop())

    def fast_stop(self) -> InputImage:
        return self._run(self._async.fast_stop())

    def acknowledge(self) -> InputImage:
        return self._run(self._async.acknowledge())

    def jog(self, direction: int, speed: float = 0.0, force: float | None = None) -> InputImage:
        return self._run(self._async.jog(direction, speed, force))

    def set_user_flags(self, if_flags: int) -> InputImage:
        return self._run(self._async.set_user_flags(if_flags))
