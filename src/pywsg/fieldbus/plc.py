"""The PLC side of the fieldbus interface: a master over any bus, and the manual's gripping cycle.

- :class:`AsyncFieldbusGripper` (asyncio) and :class:`FieldbusGripper` (blocking) drive a real WSG
  or ``wsg sim`` over any :class:`~pywsg.fieldbus.exchange.ImageExchange` (Modbus/TCP, PROFINET,
  PROFIBUS; ``open_url("modbus-tcp://HOST:PORT")`` picks it by URL) with the bus's edge semantics:
  set the parameters, raise the command flag, wait until the gripper shows the command started,
  drop the flag, wait for the result. Units: mm, mm/s, N.
- :class:`GrippingCycle` is the SCL demo of 002 Appendix D (states −1..10) ported to Python as a
  sans-IO scan function: ``step(inputs, now) -> outputs``; ``wsg plc-demo`` runs it over any bus.
  It reads the input bytes through :class:`WsgReceive`, the listing's ``WSG_RECEIVE`` struct mapped
  as an S7 PLC maps it (``receive.STW1.IDLE``, ``receive.SYSSTATE.REFERENCED``).
"""

from __future__ import annotations

import asyncio
import threading
import time
from collections.abc import Callable, Coroutine
from dataclasses import dataclass, field, replace
from typing import Any, TypeVar

from ..protocol import GState, Status, SystemFlag
from .exchange import FieldbusConnectionError, ImageExchange, open_exchange
from .image import CmdFlag, InputImage, OutputImage, force_scale

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
        from .modbus.exchange import ModbusExchange

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


# ---------------------------------------------------------------------------------------------------
# The manual's gripping cycle (002 Appendix D, SCL listing), as a sans-IO scan function.


@dataclass
class CycleConfig:
    """The listing's CycleConfig in bus units (1/100 mm, 1/100 mm/s, 1/100 N) and seconds."""

    prepos_width: int = 3000
    prepos_speed: int = 40000
    prepos_force: int = 8000
    grasp_width: int = 2200
    grasp_speed: int = 40000
    grasp_force: int = 5000
    holding_time: float = 1.0
    release_width: int = 3000
    release_speed: int = 40000
    release_force: int = 8000
    start_width: int = 6000
    start_speed: int = 40000
    start_force: int = 8000


STEP_TEXT = {
    -1: "error: reset all command flags, set STOP/ACK",
    0: "homing: wait for IDLE, reset STOP/ACK, set HOMING",
    1: "homing running? wait for POSITIONING, reset HOMING",
    2: "wait for IDLE and REFERENCED",
    3: "pre-position: MOVE to PreposWidth",
    4: "wait for POSITIONING, reset MOVE",
    5: "grip: GRIP at GraspWidth",
    6: "wait for GRIPPING, reset GRIP",
    7: "holding: hold for HoldingTime (release at once on NO_PART / PART_LOST)",
    8: "release: wait for RELEASING, reset RELEASE",
    9: "back to start: MOVE to StartWidth",
    10: "wait for POSITIONING, reset MOVE",
    11: "cycle finished: wait for IDLE, restart at step 3",
}


# TYPE "WSG_RECEIVE" of the listing (002 Appendix D, lines 5..65): names exactly as declared.
STW1_BOOLS = ("IDLE", "GRASPING", "NO_PART", "PART_LOST", "HOLDING", "RELEASING", "POSITIONING", "ERROR",
              "OF1", "OF2", "OF3", "OF4", "OF5", "OF6", "OF7", "OF8")
SYSSTATE_BOOLS = ("REFERENCED", "MOVING", "BLOCKED_MINUS", "BLOCKED_PLUS", "SOFT_LIMIT_MINUS", "SOFT_LIMIT_PLUS",
                  "AXIS_STOPPED", "TARGET_POS_REACHED", "OVERDRIVE_MODE", "FORCECNTL_MODE", "RES10", "RES11",
                  "FAST_STOP", "TEMP_WARNING", "TEMP_FAULT", "POWER_FAULT", "CURR_FAULT", "FINGER_FAULT",
                  "CMD_FAILURE", "SCRIPT_RUN", "SCRIPT_FAILURE", *(f"RES{n}" for n in range(21, 32)))


class SclBools:
    """An SCL ``Struct`` of ``Bool`` over a byte block, as an S7 PLC maps it: the k-th Bool is
    byte k // 8, bit k % 8. Read the members by name: ``receive.SYSSTATE.REFERENCED``."""

    def __init__(self, names: tuple[str, ...], block: bytes) -> None:
        if len(block) * 8 != len(names):
            raise ValueError(f"{len(names)} Bools need {len(names) // 8} bytes, got {len(block)}")
        self._bits = {name: bool(block[k // 8] >> (k % 8) & 1) for k, name in enumerate(names)}

    def __getattr__(self, name: str) -> bool:
        try:
            return self.__dict__["_bits"][name]  # type: ignore[no-any-return]
        except KeyError:
            raise AttributeError(name) from None

    def on(self) -> list[str]:
        """The names of the members that are true."""
        return [name for name, value in self._bits.items() if value]


@dataclass(frozen=True)
class WsgReceive:
    """``WSG_RECEIVE``: the 12 input bytes as the listing's PLC sees them (Int/UInt big-endian)."""

    STW1: SclBools
    SYSSTATE: SclBools
    WIDTH: int
    FORCE: int
    ERROR_CODE: int

    @classmethod
    def from_bytes(cls, data: bytes) -> WsgReceive:
        """Map the 12 received bytes onto the struct."""
        if len(data) != 12:
            raise ValueError(f"WSG_RECEIVE is 12 bytes, got {len(data)}")
        return cls(SclBools(STW1_BOOLS, data[0:2]), SclBools(SYSSTATE_BOOLS, data[2:6]),
                   int.from_bytes(data[6:8], "big", signed=True), int.from_bytes(data[8:10], "big"),
                   int.from_bytes(data[10:12], "big"))


@dataclass
class GrippingCycle:
    """The SCL ``GrippingCycle`` function block. Call :meth:`step` once per PLC scan.

    Ported faithfully, with two robustness changes (docs/fieldbus.md, docs/fidelity.md):

    - a step waiting for a *running* state (POSITIONING, GRIPPING, RELEASING) also accepts the
      state that follows it, because a fast virtual gripper can finish a short motion between two
      scans;
    - such a step treats a refused command (IDLE with an error STATUS CODE) like ERROR.

    ``recover_fast_stop`` (off by default, as the listing): every step that checks ``STW1.ERROR``
    (1..10 and the default) goes to step −1 on ``SYSSTATE.FAST_STOP`` too, doing nothing else in that
    scan. A FAST STOP sets the gripper state to IDLE, not ERROR (002 §4.6), so the listing taken
    literally waits for ever in a step that waits for a running state or for HOLDING (e.g. step 7
    when the FAST STOP strikes while GRIPPING); its error step −1 (STOP/ACK: "Acknowledge a FAST
    STOP") is the recovery the listing provides. Steps −1 and 0 are the listing's: while a fault
    refuses the acknowledge, −1 → 0 → 1 → −1 repeats, each time with a new STOP/ACK edge.
    :meth:`fast_stop_hint` says why a listing-exact cycle stopped making progress.

    ``state`` starts at 0 (homing); the listing's initial -2 falls into the default branch, which
    restarts at step 3 without homing.
    """

    config: CycleConfig = field(default_factory=CycleConfig)
    state: int = 0
    recover_fast_stop: bool = False
    send: OutputImage = field(default_factory=OutputImage)
    holding_active: bool = False
    timer_due: float | None = None
    cycles: int = 0
    error_count: int = 0
    holds: int = 0
    no_part: int = 0
    log: Callable[[str], None] | None = None
    # The last few transitions logged: a loop (-1 -> 0 -> 1 -> -1 while a fault refuses every
    # command) is logged once, then summed up when something else happens.
    _recent: list[str] = field(default_factory=list, repr=False)
    _repeated: int = field(default=0, repr=False)

    def _set(self, on: CmdFlag = CmdFlag.NONE, off: CmdFlag = CmdFlag.NONE, **params: int) -> None:
        self.send = replace(self.send, cmdflags=(self.send.cmdflags | on) & ~off, **params)

    def _say(self, text: str) -> None:
        if self.log is None:
            return
        if text in self._recent:
            self._repeated += 1
            return
        if self._repeated:
            self.log(f"        ... the steps above repeated ({self._repeated} more transitions)")
            self._repeated = 0
        self._recent = [*self._recent[-2:], text]
        self.log(text)

    def step(self, receive: InputImage | WsgReceive, now: float) -> OutputImage:
        """One scan: read ``receive`` (as ``WSG_RECEIVE``), run the CASE, return the outputs to write."""
        rcv = receive if isinstance(receive, WsgReceive) else WsgReceive.from_bytes(receive.pack())
        stw1, sysstate = rcv.STW1, rcv.SYSSTATE
        cfg = self.config
        timer_expired = self.timer_due is not None and now >= self.timer_due
        do_next = False
        state = self.state
        error = stw1.ERROR
        ok = rcv.ERROR_CODE == Status.E_SUCCESS
        # Port addition: a command the gripper refused leaves it IDLE with an error STATUS CODE; the
        # steps waiting for a running state treat that like ERROR instead of waiting forever.
        refused = stw1.IDLE and rcv.ERROR_CODE not in (Status.E_SUCCESS, Status.E_CMD_PENDING)

        if self.recover_fast_stop and sysstate.FAST_STOP and state > 0:
            # Option, not the listing: a FAST STOP shows IDLE, not ERROR (002 §4.6), but is an error to
            # acknowledge (App. B D12), which step -1 does. Like the listing's ERROR check, it replaces
            # the step (with ERROR none of a step's IDLE / running-state conditions can hold either).
            self.state = -1
        elif state == -1:
            self.error_count += 1
            self._set(on=CmdFlag.STOP_ACK, off=CmdFlag.FASTSTOP | CmdFlag.GRIP | CmdFlag.HOMING
                      | CmdFlag.JOG_MINUS | CmdFlag.JOG_PLUS | CmdFlag.MOVE | CmdFlag.RELEASE)
            do_next = True
        elif state == 0:
            if not stw1.IDLE:
                self.state = -1
            else:
                self._set(on=CmdFlag.HOMING, off=CmdFlag.STOP_ACK)
                do_next = True
        elif state == 1:
            if error or refused:
                self.state = -1
            # POSITIONING while homing; IDLE and REFERENCED if homing finished between two scans.
            if stw1.POSITIONING or (stw1.IDLE and ok and sysstate.REFERENCED):
                self._set(off=CmdFlag.HOMING)
                do_next = True
        elif state == 2:
            if error:
                self.state = -1
            if stw1.IDLE:
                if not sysstate.REFERENCED:
                    self.state = -1
                else:
                    do_next = True
        elif state == 3:
            if error:
                self.state = -1
            if stw1.IDLE:
                self._set(on=CmdFlag.MOVE, width=cfg.prepos_width, speed=cfg.prepos_speed,
                          force_limit=cfg.prepos_force)
                do_next = True
        elif state == 4:
            if error or refused:
                self.state = -1
            if stw1.POSITIONING or (stw1.IDLE and ok):
                self._set(off=CmdFlag.MOVE)
                do_next = True
        elif state == 5:
            if error:
                self.state = -1
            if stw1.IDLE:
                self._set(on=CmdFlag.GRIP, width=cfg.grasp_width, speed=cfg.grasp_speed,
                          force_limit=cfg.grasp_force)
                do_next = True
        elif state == 6:
            if error or refused:
                self.state = -1
            if stw1.GRASPING or stw1.HOLDING or stw1.NO_PART or stw1.PART_LOST:
                self._set(off=CmdFlag.GRIP)
                do_next = True
        elif state == 7:
            if error:
                self.state = -1
            if stw1.HOLDING and not self.holding_active:
                self.holding_active = True
                self.holds += 1
                self.timer_due = now + cfg.holding_time
                timer_expired = False
            if timer_expired or stw1.NO_PART or stw1.PART_LOST:
                if stw1.NO_PART:
                    self.no_part += 1
                self.holding_active = False
                self.timer_due = None
                self._set(on=CmdFlag.RELEASE, width=cfg.release_width, speed=cfg.release_speed,
                          force_limit=cfg.release_force)
                do_next = True
        elif state == 8:
            if error or refused:
                self.state = -1
            if stw1.RELEASING or (stw1.IDLE and ok):
                self._set(off=CmdFlag.RELEASE)
                do_next = True
        elif state == 9:
            if error:
                self.state = -1
            if stw1.IDLE:
                self._set(on=CmdFlag.MOVE, width=cfg.start_width, speed=cfg.start_speed,
                          force_limit=cfg.start_force)
                do_next = True
        elif state == 10:
            if error or refused:
                self.state = -1
            if stw1.POSITIONING or (stw1.IDLE and ok):
                self._set(off=CmdFlag.MOVE)
                do_next = True
        else:  # default: state not in -1..10
            if error:
                self.state = -1
            if stw1.IDLE:
                self.state = 3
                self.cycles += 1

        if do_next:
            self.state += 1
        if self.state != state:
            self._say(f"step {state:>2} -> {self.state:>2}: {STEP_TEXT.get(self.state, 'default branch')}"
                      f"  [{_gstate_name(stw1)}, {_status_name(rcv.ERROR_CODE)}]")
        return self.send

    def fast_stop_hint(self, receive: InputImage | WsgReceive) -> str | None:
        """Why the cycle may wait for ever: FAST STOP set while it runs the listing exactly, else None."""
        rcv = receive if isinstance(receive, WsgReceive) else WsgReceive.from_bytes(receive.pack())
        if self.recover_fast_stop or not rcv.SYSSTATE.FAST_STOP:
            return None
        return (f"step {self.state} ({STEP_TEXT.get(self.state, 'default branch')}) with FAST STOP set and gripper "
                f"state {_gstate_name(rcv.STW1)}: the listing (002 App. D) leaves a step for its error step only "
                "on ERROR, and a FAST STOP sets IDLE (002 §4.6); --recover-fast-stop treats FAST STOP like ERROR")


GSTATE_NAMES = {"GRASPING": GState.GRIPPING.name}
"""The listing's Bool names (STW1) that differ from the gripper state's name."""


def _status_name(code: int) -> str:
    try:
        return Status(code).name
    except ValueError:
        return str(code)


def _gstate_name(stw1: SclBools) -> str:
    """The gripper state named in STW1 (one-hot) by its one name: the listing's Bool GRASPING is the
    state GRIPPING (000 §3.4.2), which the step texts beside it name too."""
    states = [GSTATE_NAMES.get(name, name) for name in STW1_BOOLS[:8] if getattr(stw1, name)]
    return states[0] if len(states) == 1 else f"GSTATE={'+'.join(states) or '0'}"


__all__ = [
    "AsyncFieldbusGripper", "CycleConfig", "FieldbusConnectionError", "FieldbusError", "FieldbusGripper",
    "GrippingCycle", "SclBools", "WsgReceive",
]
