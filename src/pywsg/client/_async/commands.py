"""The gripper's commands as methods, said once: :class:`AsyncCommands` (mixed into
:class:`~pywsg.client.AsyncGripper`) and :class:`AsyncFinger`.

This file is the source: ``_sync/generated_commands.py`` (``Commands`` and ``Finger`` of the blocking
:class:`~pywsg.client.Gripper`) is generated from it by ``scripts/unasync_client.py`` (``async
def`` -> ``def``, ``await`` dropped, ``Async*`` -> ``*``), the way httpcore keeps its sync and async
code from drifting; ``tests/client/test_unasync.py`` fails when the two differ. Each method is one
line: what the request is and how its reply decodes live in :mod:`pywsg.client.calls` (built from
the catalog); the shell only supplies ``_run`` (an immediate command) and ``_run_motion`` (a command
that may answer E_CMD_PENDING and a final frame later). Commands whose I/O differs between the
shells (``state()``, ``subscribe()``, ``request()``) stay in the shells.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, TypeVar

from ...protocol import FingerFlag, GripperState, HomingDirection, SystemFlag
from .. import calls
from ..calls import Call
from ..types import FingerInfo, Limits, SoftLimits, Statistics, SystemInfo

if TYPE_CHECKING:
    from .handles import AsyncMotion

T = TypeVar("T")


class AsyncCommands:
    """The command methods of the driver (000 §3: one method per command)."""

    __slots__ = ()

    if TYPE_CHECKING:  # supplied by the shell
        async def _run(self, call: Call[T], timeout: float | None = None) -> T: ...

        async def _run_motion(self, call: Call[Any], wait: bool, timeout: float | None) -> AsyncMotion: ...

    # ------------------------------------------------------------------ connection
    async def loop(self, data: bytes = b"pywsg") -> bytes:
        """06h Loop: the gripper returns ``data`` (at most 256 bytes)."""
        return await self._run(calls.loop(data))

    # ------------------------------------------------------------------ motion
    async def home(self, direction: HomingDirection | int | str | None = None, *, wait: bool = True,
                   timeout: float | None = None) -> AsyncMotion:
        """20h Homing: reference the fingers (direction None/0: default, 1 positive, 2 negative)."""
        return await self._run_motion(calls.homing(direction), wait, timeout)

    async def move(self, width: float, speed: float, relative: bool = False, stop_on_block: bool = False, *,
                   wait: bool = True, timeout: float | None = None) -> AsyncMotion:
        """21h Pre-position: move to ``width`` mm (or by it, ``relative``) at ``speed`` mm/s."""
        return await self._run_motion(calls.preposition(width, speed, relative, stop_on_block), wait, timeout)

    async def grip(self, width: float, speed: float, force: float | None = None, *, wait: bool = True,
                   timeout: float | None = None) -> AsyncMotion:
        """25h Grip Part of nominal ``width`` mm at ``speed`` mm/s; ``force`` N sets the force limit first.
        Raises NoPartError when no part is found within the clamping travel."""
        if force is not None:
            await self.set_force_limit(force)
        return await self._run_motion(calls.grip(width, speed), wait, timeout)

    async def release(self, width: float, speed: float, *, wait: bool = True,
                      timeout: float | None = None) -> AsyncMotion:
        """26h Release Part: open to ``width`` mm at ``speed`` mm/s."""
        return await self._run_motion(calls.release(width, speed), wait, timeout)

    async def stop(self) -> None:
        """22h Stop: end any motion (that motion ends with AbortedError)."""
        await self._run(calls.stop())

    async def fast_stop(self) -> None:
        """23h FAST STOP: motion commands are refused until ``acknowledge()``."""
        await self._run(calls.fast_stop())

    async def acknowledge(self) -> None:
        """24h Acknowledge FAST STOP (sends the key "ack")."""
        await self._run(calls.acknowledge())

    # ------------------------------------------------------------------ motion configuration
    async def set_acceleration(self, acceleration: float) -> None:
        """30h: acceleration in mm/s² (clamped by the gripper to its limits)."""
        await self._run(calls.set_acceleration(acceleration))

    async def acceleration(self) -> float:
        """31h: the set acceleration, mm/s²."""
        return await self._run(calls.acceleration())

    async def set_force_limit(self, force: float) -> None:
        """32h: gripping force limit in N (clamped to the nominal or overdrive force)."""
        await self._run(calls.set_force_limit(force))

    async def force_limit(self) -> float:
        """33h: the force limit, N."""
        return await self._run(calls.force_limit())

    async def set_soft_limits(self, minus: float, plus: float) -> None:
        """34h: soft limits in mm (a motion beyond them: RangeError)."""
        await self._run(calls.set_soft_limits(minus, plus))

    async def soft_limits(self) -> SoftLimits | None:
        """35h: the soft limits in mm, or None when none are set."""
        return await self._run(calls.soft_limits())

    async def clear_soft_limits(self) -> None:
        """36h: clear the soft limits."""
        await self._run(calls.clear_soft_limits())

    async def overdrive(self, enable: bool = True) -> None:
        """37h: enable (or disable) force overdrive mode."""
        await self._run(calls.overdrive(enable))

    async def tare(self) -> None:
        """38h: zero the force sensor (not while HOLDING: AccessDeniedError)."""
        await self._run(calls.tare())

    # ------------------------------------------------------------------ state
    async def system_state(self) -> SystemFlag:
        """40h: the system state flags."""
        return await self._run(calls.system_state())

    async def gripper_state(self) -> GripperState | int:
        """41h: the grasping state (IDLE, HOLDING, NO_PART, ...)."""
        return await self._run(calls.gripper_state())

    async def statistics(self, reset: bool = False) -> Statistics:
        """42h: grips total / no part / part lost (``reset`` clears them after reading)."""
        return await self._run(calls.statistics(reset))

    async def width(self) -> float:
        """43h: opening width, mm."""
        return await self._run(calls.width())

    async def speed(self) -> float:
        """44h: finger speed, mm/s."""
        return await self._run(calls.speed())

    async def force(self) -> float:
        """45h: gripping force, N."""
        return await self._run(calls.force())

    async def temperature(self) -> float:
        """46h: device temperature, °C."""
        return await self._run(calls.temperature())

    # ------------------------------------------------------------------ system
    async def info(self) -> SystemInfo:
        """50h: device type, hardware revision, firmware version, serial number."""
        return await self._run(calls.info())

    async def set_tag(self, tag: str) -> None:
        """51h: set the device tag (at most 64 printable ASCII characters)."""
        await self._run(calls.set_tag(tag))

    async def tag(self) -> str | None:
        """52h: the device tag, or None when none is set."""
        return await self._run(calls.tag())

    async def limits(self) -> Limits:
        """53h: stroke (mm), speed (mm/s), acceleration (mm/s²) and force (N) limits."""
        return await self._run(calls.limits())

    def finger(self, n: int) -> AsyncFinger:
        """Finger 1 or 2 (60h..63h, 70h..73h)."""
        return AsyncFinger(self, n)


class AsyncFinger:
    """Finger 1 or 2: ``await g.finger(1).info()``."""

    def __init__(self, gripper: AsyncCommands, n: int) -> None:
        calls.finger_info(n)  # validates n
        self._g = gripper
        self.n = n

    async def info(self) -> FingerInfo:
        """60h/70h: finger type and data frame size (bytes)."""
        return await self._g._run(calls.finger_info(self.n))

    async def flags(self) -> FingerFlag:
        """61h/71h: finger state flags."""
        return await self._g._run(calls.finger_flags(self.n))

    async def power(self, on: bool = True, *, timeout: float | None = None) -> None:
        """62h/72h: switch the finger's power (switching on takes ~500 ms: waits for it)."""
        await self._g._run_motion(calls.finger_power(self.n, on), True, timeout)

    async def data(self) -> bytes:
        """63h/73h: the finger's current data frame (layout depends on the finger)."""
        return await self._g._run(calls.finger_data(self.n))
