"""GENERATED from ``pywsg/client/_async/commands.py`` by ``scripts/unasync_client.py`` - do not
edit; edit the source and run the script. The command methods of the blocking
:class:`~pywsg.client.Gripper`: :class:`Commands` (mixed into it) and :class:`Finger`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, TypeVar

from ...protocol import FingerFlag, GripperState, HomingDirection, SystemFlag
from .. import calls
from ..calls import Call
from ..types import FingerInfo, Limits, SoftLimits, Statistics, SystemInfo

if TYPE_CHECKING:
    from .handles import Motion

T = TypeVar("T")


class Commands:
    """The command methods of the driver (000 §3: one method per command)."""

    __slots__ = ()

    if TYPE_CHECKING:  # supplied by the shell
        def _run(self, call: Call[T], timeout: float | None = None) -> T: ...

        def _run_motion(self, call: Call[Any], wait: bool, timeout: float | None) -> Motion: ...

    # ------------------------------------------------------------------ connection
    def loop(self, data: bytes = b"pywsg") -> bytes:
        """06h Loop: the gripper returns ``data`` (at most 256 bytes)."""
        return self._run(calls.loop(data))

    # ------------------------------------------------------------------ motion
    def home(self, direction: HomingDirection | int | str | None = None, *, wait: bool = True,
             timeout: float | None = None) -> Motion:
        """20h Homing: reference the fingers (direction None/0: default, 1 positive, 2 negative)."""
        return self._run_motion(calls.homing(direction), wait, timeout)

    def move(self, width: float, speed: float, relative: bool = False, stop_on_block: bool = False, *,
             wait: bool = True, timeout: float | None = None) -> Motion:
        """21h Pre-position: move to ``width`` mm (or by it, ``relative``) at ``speed`` mm/s."""
        return self._run_motion(calls.preposition(width, speed, relative, stop_on_block), wait, timeout)

    def grip(self, width: float, speed: float, force: float | None = None, *, wait: bool = True,
             timeout: float | None = None) -> Motion:
        """25h Grip Part of nominal ``width`` mm at ``speed`` mm/s; ``force`` N sets the force limit first.
        Raises NoPartError when no part is found within the clamping travel."""
        if force is not None:
            self.set_force_limit(force)
        return self._run_motion(calls.grip(width, speed), wait, timeout)

    def release(self, width: float, speed: float, *, wait: bool = True,
                timeout: float | None = None) -> Motion:
        """26h Release Part: open to ``width`` mm at ``speed`` mm/s."""
        return self._run_motion(calls.release(width, speed), wait, timeout)

    def stop(self) -> None:
        """22h Stop: end any motion (that motion ends with AbortedError)."""
        self._run(calls.stop())

    def fast_stop(self) -> None:
        """23h FAST STOP: motion commands are refused until ``acknowledge()``."""
        self._run(calls.fast_stop())

    def acknowledge(self) -> None:
        """24h Acknowledge FAST STOP (sends the key "ack")."""
        self._run(calls.acknowledge())

    # ------------------------------------------------------------------ motion configuration
    def set_acceleration(self, acceleration: float) -> None:
        """30h: acceleration in mm/s² (clamped by the gripper to its limits)."""
        self._run(calls.set_acceleration(acceleration))

    def acceleration(self) -> float:
        """31h: the set acceleration, mm/s²."""
        return self._run(calls.acceleration())

    def set_force_limit(self, force: float) -> None:
        """32h: gripping force limit in N (clamped to the nominal or overdrive force)."""
        self._run(calls.set_force_limit(force))

    def force_limit(self) -> float:
        """33h: the force limit, N."""
        return self._run(calls.force_limit())

    def set_soft_limits(self, minus: float, plus: float) -> None:
        """34h: soft limits in mm (a motion beyond them: RangeError)."""
        self._run(calls.set_soft_limits(minus, plus))

    def soft_limits(self) -> SoftLimits | None:
        """35h: the soft limits in mm, or None when none are set."""
        return self._run(calls.soft_limits())

    def clear_soft_limits(self) -> None:
        """36h: clear the soft limits."""
        self._run(calls.clear_soft_limits())

    def overdrive(self, enable: bool = True) -> None:
        """37h: enable (or disable) force overdrive mode."""
        self._run(calls.overdrive(enable))

    def tare(self) -> None:
        """38h: zero the force sensor (not while HOLDING: AccessDeniedError)."""
        self._run(calls.tare())

    # ------------------------------------------------------------------ state
    def system_state(self) -> SystemFlag:
        """40h: the system state flags."""
        return self._run(calls.system_state())

    def gripper_state(self) -> GripperState | int:
        """41h: the grasping state (IDLE, HOLDING, NO_PART, ...)."""
        return self._run(calls.gripper_state())

    def statistics(self, reset: bool = False) -> Statistics:
        """42h: grips total / no part / part lost (``reset`` clears them after reading)."""
        return self._run(calls.statistics(reset))

    def width(self) -> float:
        """43h: opening width, mm."""
        return self._run(calls.width())

    def speed(self) -> float:
        """44h: finger speed, mm/s."""
        return self._run(calls.speed())

    def force(self) -> float:
        """45h: gripping force, N."""
        return self._run(calls.force())

    def temperature(self) -> float:
        """46h: device temperature, °C."""
        return self._run(calls.temperature())

    # ------------------------------------------------------------------ system
    def info(self) -> SystemInfo:
        """50h: device type, hardware revision, firmware version, serial number."""
        return self._run(calls.info())

    def set_tag(self, tag: str) -> None:
        """51h: set the device tag (at most 64 printable ASCII characters)."""
        self._run(calls.set_tag(tag))

    def tag(self) -> str | None:
        """52h: the device tag, or None when none is set."""
        return self._run(calls.tag())

    def limits(self) -> Limits:
        """53h: stroke (mm), speed (mm/s), acceleration (mm/s²) and force (N) limits."""
        return self._run(calls.limits())

    def finger(self, n: int) -> Finger:
        """Finger 1 or 2 (60h..63h, 70h..73h)."""
        return Finger(self, n)


class Finger:
    """Finger 1 or 2: ``g.finger(1).info()``."""

    def __init__(self, gripper: Commands, n: int) -> None:
        calls.finger_info(n)  # validates n
        self._g = gripper
        self.n = n

    def info(self) -> FingerInfo:
        """60h/70h: finger type and data frame size (bytes)."""
        return self._g._run(calls.finger_info(self.n))

    def flags(self) -> FingerFlag:
        """61h/71h: finger state flags."""
        return self._g._run(calls.finger_flags(self.n))

    def power(self, on: bool = True, *, timeout: float | None = None) -> None:
        """62h/72h: switch the finger's power (switching on takes ~500 ms: waits for it)."""
        self._g._run_motion(calls.finger_power(self.n, on), True, timeout)

    def data(self) -> bytes:
        """63h/73h: the finger's current data frame (layout depends on the finger)."""
        return self._g._run(calls.finger_data(self.n))
