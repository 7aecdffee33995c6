"""The PLC side, asyncio: :class:`AsyncFieldbusGripper` drives a WSG over any
:class:`~pywsg.fieldbus.exchange.ImageExchange` with the output image's commands (002 §4.1–4.7) and
their edge semantics: set the parameters, raise the command flag, wait until the gripper shows the
command started, drop the flag, wait for the result. Units: mm, mm/s, N.
"""

from __future__ import annotations

import asyncio
import time
from collections.abc import Callable
from dataclasses import replace
from typing import TypeVar

from ...protocol import GState, Status, SystemFlag
from ..exchange import ImageExchange, open_exchange
from ..image import CmdFlag, InputImage, OutputImage, force_scale

T = TypeVar("T")


_RUNNING = {
    CmdFlag.MOVE: GState.POSITIONING,
    CmdFlag.HOMING: GState.POSITIONING,
    CmdFlag.GRIP: GState.GRIPPING,
    CmdFlag.RELEASE: GState.RELEASING,
}


class FieldbusError(Exception):
    """A fieldbus command ended with an error STATUS CODE (or timed out); ``image`` is the last input."""

    def __init__(self, message: str, image: InputImage | None = None) -> None:
        super().__init__(message)
        self.image = image
        self.status: Status | int | None = image.status_code if image is not None else None


class AsyncFieldbusGripper:
    """Fieldbus master for the WSG (asyncio) over any :class:`~pywsg.fieldbus.exchange.ImageExchange`.

    ``model`` selects the force unit (1/10 N on "wsg70"). ``poll_interval`` is the bus cycle used
    while waiting, in seconds. A connection failure is a
    :class:`~pywsg.fieldbus.exchange.FieldbusConnectionError` (a ConnectionError), whatever the bus.
    """

    def __init__(self, exchange: ImageExchange, model: str = "wsg50", poll_interval: float = 0.002) -> None:
        self.exchange = exchange
        self.model = model
        self.poll_interval = poll_interval
        self.outputs = OutputImage()
        self.inputs = InputImage()

    @classmethod
    async def open_url(cls, url: str, *, model: str = "wsg50", timeout: float = 3.0,
                       poll_interval: float = 0.002) -> AsyncFieldbusGripper:
        """Open the bus named by ``url`` (:func:`~pywsg.fieldbus.exchange.open_exchange`:
        ``modbus-tcp://HOST[:PORT]``, ``profinet://IFACE/STATION``, ``profibus://PORT?address=N``);
        ``timeout`` in s per exchange. ValueError for a bad URL, FieldbusConnectionError when the
        gripper cannot be reached."""
        return await cls.start(await open_exchange(url, timeout=timeout), model=model, poll_interval=poll_interval)

    @classmethod
    async def open(cls, host: str = "127.0.0.1", port: int = 502, *, model: str = "wsg50",
                   device_id: int = 1, timeout: float = 3.0, poll_interval: float = 0.002) -> AsyncFieldbusGripper:
        """Connect over Modbus/TCP to ``host:port``; ``timeout`` in s per request.

        Raises :class:`FieldbusConnectionError` (a ConnectionError) when the connection is refused or
        the peer does not answer Modbus within ``timeout``.
        """
        from ..modbus.exchange import ModbusExchange

        exchange = await ModbusExchange.open(host, port, device_id=device_id, timeout=timeout)
        return await cls.start(exchange, model=model, poll_interval=poll_interval)

    @classmethod
    async def start(cls, exchange: ImageExchange, *, model: str = "wsg50",
                    poll_interval: float = 0.002) -> AsyncFieldbusGripper:
        """Wrap an open exchange; closes it if the first exchange fails. When the bus can read back
        the outputs the gripper holds (an optional ``read_outputs()``, Modbus/TCP), start from them so
        that opening never fires an edge."""
        self = cls(exchange, model, poll_interval)
        read_outputs = getattr(exchange, "read_outputs", None)
        if read_outputs is not None:
            try:
                self.outputs = OutputImage.unpack(await read_outputs())
            except BaseException:
                await exchange.close()
                raise
        return self

    async def close(self) -> None:
        """Leave the bus."""
        await self.exchange.close()

    async def __aenter__(self) -> AsyncFieldbusGripper:
        return self

    async def __aexit__(self, *exc: object) -> None:
        await self.close()

    # --- one bus cycle -------------------------------------------------------------------------
    # --- one bus cycle -------------------------------------------------------------------------
    async def read(self) -> InputImage:
        """Read the 12 input bytes."""
        try:
            self.inputs = InputImage.unpack(await self.exchange.read_inputs())
        except (ConnectionError, ValueError):
            raise
        except Exception as exc:   # the bus answered with an error (e.g. a Modbus exception)
            raise FieldbusError(f"reading the inputs failed: {exc}") from exc
        return self.inputs

    async def write(self, image: OutputImage) -> None:
        """Write the 8 output bytes."""
        try:
            await self.exchange.write_outputs(image.pack())
        except (ConnectionError, ValueError):
            raise
        except Exception as exc:
            raise FieldbusError(f"writing the outputs failed: {exc}") from exc
        self.outputs = image

    async def cycle(self, image: OutputImage | None = None) -> InputImage:
        """One bus cycle: write the outputs (the current ones if None), read the inputs."""
        await self.write(self.outputs if image is None else image)
        return await self.read()

    # --- commands ------------------------------------------------------------------------------
    # --- commands ------------------------------------------------------------------------------
    def _params(self, width: float | None, speed: float | None, force: float | None) -> OutputImage:
        out = self.outputs
        return replace(
            out,
            width=out.width if width is None else round(width * 100),
            speed=out.speed if speed is None else round(speed * 100),
            force_limit=out.force_limit if force is None else round(force * force_scale(self.model)),
        )

    async def _wait(self, done: Callable[[InputImage], bool], timeout: float, what: str) -> InputImage:
        deadline = time.monotonic() + timeout
        while True:
            inputs = await self.read()
            if done(inputs):
                return inputs
            if time.monotonic() > deadline:
                raise FieldbusError(f"{what}: timed out after {timeout:g} s", inputs)
            await asyncio.sleep(self.poll_interval)

    async def command(self, flag: CmdFlag, *, width: float | None = None, speed: float | None = None,
                      force: float | None = None, wait: bool = True, timeout: float = 10.0) -> InputImage:
        """Issue one edge command: parameters + raise ``flag``; wait until started; drop the flag.

        With ``wait`` the result is awaited too: returns the input image, raises FieldbusError when
        STATUS CODE is an error. Widths mm, speeds mm/s, forces N.
        """
        base = self._params(width, speed, force)
        if base.cmdflags & flag:   # make sure there is an edge
            base = replace(base, cmdflags=base.cmdflags & ~flag)
            await self.write(base)
        await self.write(replace(base, cmdflags=base.cmdflags | flag))
        running = _RUNNING.get(flag)
        target = base.width if flag == CmdFlag.MOVE else None

        def started(i: InputImage) -> bool:
            if i.status == Status.E_CMD_PENDING or (running is not None and i.gstate & running):
                return True
            if (target is not None and i.status == Status.E_SUCCESS and abs(i.width - target) <= 1
                    and i.sysstate & SystemFlag.SF_TARGET_POS_REACHED):
                return True  # a MOVE to where the fingers already are can end before the first read
            if flag == CmdFlag.FASTSTOP:
                return bool(i.sysstate & SystemFlag.SF_FAST_STOP)
            if flag == CmdFlag.STOP_ACK:
                return not i.sysstate & SystemFlag.SF_FAST_STOP or i.status != Status.E_SUCCESS
            return i.status != Status.E_SUCCESS   # an immediate error

        try:
            inputs = await self._wait(started, timeout, flag.name or "command")
        finally:
            await self.write(replace(self.outputs, cmdflags=self.outputs.cmdflags & ~flag))
        if wait and running is not None:
            inputs = await self._wait(lambda i: i.status != Status.E_CMD_PENDING, timeout, flag.name or "")
        if inputs.status not in (Status.E_SUCCESS, Status.E_CMD_PENDING):
            raise FieldbusError(f"{flag.name}: {Status.describe(inputs.status)}", inputs)
        return inputs

    async def homing(self, timeout: float = 10.0) -> InputImage:
        """Reference the gripper (HOMING)."""
        return await self.command(CmdFlag.HOMING, timeout=timeout)

    async def move(self, width: float, speed: float, force: float | None = None, wait: bool = True,
                   timeout: float = 10.0) -> InputImage:
        """Pre-position to ``width`` mm at ``speed`` mm/s (MOVE); ``force`` N optional."""
        return await self.command(CmdFlag.MOVE, width=width, speed=speed, force=force, wait=wait, timeout=timeout)

    async def grip(self, width: float, speed: float, force: float, wait: bool = True,
                   timeout: float = 10.0) -> InputImage:
        """Grip a part of nominal ``width`` mm at ``speed`` mm/s with ``force`` N (GRIP)."""
        return await self.command(CmdFlag.GRIP, width=width, speed=speed, force=force, wait=wait, timeout=timeout)

    async def release(self, width: float, speed: float, wait: bool = True, timeout: float = 10.0) -> InputImage:
        """Release to ``width`` mm at ``speed`` mm/s (RELEASE)."""
        return await self.command(CmdFlag.RELEASE, width=width, speed=speed, wait=wait, timeout=timeout)

    async def stop(self) -> InputImage:
        """STOP/ACK when no FAST STOP is pending: stop the fingers."""
        return await self.command(CmdFlag.STOP_ACK)

    async def fast_stop(self) -> InputImage:
        """Raise a FAST STOP (FASTSTOP edge; the flag is dropped again afterwards)."""
        return await self.command(CmdFlag.FASTSTOP)

    async def acknowledge(self) -> InputImage:
        """Acknowledge a FAST STOP (STOP/ACK edge with FASTSTOP at 0)."""
        return await self.command(CmdFlag.STOP_ACK)

    async def jog(self, direction: int, speed: float = 0.0, force: float | None = None) -> InputImage:
        """Jog mode (levels): direction +1 / -1 sets JOG+ / JOG-, 0 clears both. Speed 0: minimum."""
        flags = self.outputs.cmdflags & ~(CmdFlag.JOG_PLUS | CmdFlag.JOG_MINUS)
        if direction > 0:
            flags |= CmdFlag.JOG_PLUS
        elif direction < 0:
            flags |= CmdFlag.JOG_MINUS
        out = replace(self._params(None, speed, force), cmdflags=flags)
        return await self.cycle(out)

    async def set_user_flags(self, if_flags: int) -> InputImage:
        """Write IF1..IF8 (bit 0 = IF1) for on-board scripts."""
        return await self.cycle(replace(self.outputs, if_flags=if_flags & 0xFF))
