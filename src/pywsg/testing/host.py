"""A virtual gripper served from a background thread, for blocking code, other loops and pytest.

::

    from pywsg.testing import SimThread
    from pywsg.client import Gripper

    with SimThread(model="wsg50") as sim:          # TCP and UDP on free loopback ports
        sim.world.place_part(22.0)
        with Gripper(sim.url) as g:
            g.home(); g.grip(22.0, speed=100)

The server runs on its own asyncio loop in a daemon thread, so a blocking client in the calling
thread (or an asyncio client on another loop) never blocks it. ``run(coro)`` and ``call(fn)`` execute
on that loop: device state is only touched there. Several SimThreads may share one
:class:`LoopThread` (the pytest plugin does, which makes a fresh gripper cost only its sockets).
"""

from __future__ import annotations

import asyncio
import functools
import threading
from collections.abc import Callable, Coroutine
from concurrent.futures import Future
from pathlib import Path
from typing import Any, TypeVar

from ..device import ManualClock, ScaledClock, Settings, VirtualGripper
from ..server.sim import SimGripper, SimOptions, SimServer
from .replay import ReplayReport, replay
from .scenario import Scenario, ScenarioRunner, drive_realtime, tap
from .world import WorldActions, apply, world_state

__all__ = ["CellGripper", "LoopThread", "SimThread", "World", "setup_world"]

S = TypeVar("S", bound="SimThread")
T = TypeVar("T")


class LoopThread:
    """An asyncio loop running forever in a daemon thread."""

    def __init__(self, name: str = "pywsg-sim") -> None:
        self.loop = asyncio.new_event_loop()
        self._thread = threading.Thread(target=self.loop.run_forever, name=name, daemon=True)
        self._thread.start()

    def run(self, coro: Coroutine[Any, Any, T], timeout: float | None = 10) -> T:
        """Run ``coro`` on the loop and wait for its result (raises what it raises)."""
        if threading.current_thread() is self._thread:
            coro.close()
            raise RuntimeError("LoopThread.run() called from its own loop: await the coroutine instead")
        fut: Future[T] = asyncio.run_coroutine_threadsafe(coro, self.loop)
        return fut.result(timeout)

    def call(self, fn: Callable[[], T], timeout: float | None = 10) -> T:
        """Run ``fn()`` on the loop thread and return its result."""

        async def _do() -> T:
            return fn()

        return self.run(_do(), timeout)

    def close(self) -> None:
        if self.loop.is_closed():
            return
        self.loop.call_soon_threadsafe(self.loop.stop)
        self._thread.join(5)
        self.loop.close()


class World(WorldActions):
    """The world around one gripper of a :class:`SimThread`: parts, obstacles, faults, heat, time.

    Every method runs on the server's loop and returns once the device has taken the change.
    Widths in mm, stiffness in N/mm, ``delta_c`` in °C, ``dt`` in s.
    """

    def __init__(self, host: SimThread, index: int = 0) -> None:
        self._host = host
        self._index = index

    def _apply(self, action: str, **params: Any) -> str:
        g = self._host.sim.grippers[self._index].gripper
        return self._host.call(lambda: apply(g, action, params))

    def state(self) -> dict[str, Any]:
        """Gripper state, width, force, temperature, part, obstacle and faults (see ``world_state``)."""
        g = self._host.sim.grippers[self._index].gripper
        return self._host.call(lambda: world_state(g))

    @property
    def manual(self) -> bool:
        """True when time only moves through :meth:`advance` (a ManualClock)."""
        return self._host.clock is not None

    def advance(self, dt: float) -> float:
        """Move a manual clock on by ``dt`` s, serving every device event and scenario action in time
        order (replies reach the clients); returns the new time. Real-clock grippers raise RuntimeError."""
        clock = self._host.clock
        if clock is None:
            raise RuntimeError("advance() needs a manual clock: start the sim with clock='manual'")
        if not dt >= 0:
            raise ValueError("dt: must be a non-negative number of seconds")
        host = self._host
        # the grippers of a cell share the clock: every one of them is served up to the new time
        cell = [(sg, host.scenario_runners.get(sg.index)) for sg in host.sim.grippers]
        return host.call(lambda: _step_all(cell, clock, clock.now + dt))


def _settings_factory(given: dict[str, Any] | Settings) -> Callable[[str, Any, Any], Any]:
    """A SimServer factory that starts each gripper with ``given`` settings (validated now)."""
    base = given if isinstance(given, Settings) else Settings().updated(**given)
    base.validate()

    def make(model: str, _file_settings: Any, clock: Any) -> VirtualGripper:
        return VirtualGripper(model, settings=base, **({"clock": clock} if clock is not None else {}))

    return make


def _cancel(task: asyncio.Task[None]) -> None:
    task.cancel()


def setup_world(sim: SimServer, *, part: float | None = None, block: float | None = None,
                scenario: Scenario | None = None, runners: dict[int, ScenarioRunner] | None = None,
                realtime: bool = True, on_action: Callable[[int, float, str], None] | None = None
                ) -> Callable[[], None]:
    """Prepare every gripper of a started ``sim`` (call on its loop): a part of ``part`` mm between the
    fingers, an obstacle at ``block`` mm, and ``scenario`` running (its actions reported through
    ``on_action(gripper index, t, text)``; timed actions on the loop when ``realtime``, else through
    :meth:`World.advance`). Returns a function that stops the scenarios. Raises WorldError."""
    undo: list[Callable[[], None]] = []
    for sg in sim.grippers:
        g: Any = sg.gripper
        if part is not None:
            apply(g, "part", {"width": part})
        if block is not None:
            apply(g, "block", {"width": block})
        if scenario is None:
            continue
        report: Callable[[float, str], None] | None = None
        if on_action is not None:
            def report(t: float, text: str, i: int = sg.index, fn: Callable[[int, float, str], None] = on_action
                       ) -> None:
                fn(i, t, text)
        runner = ScenarioRunner(scenario, g, start=g.clock(), on_action=report)
        if runners is not None:
            runners[sg.index] = runner
        undo.append(tap(g, runner))
        if realtime:
            task = asyncio.get_running_loop().create_task(drive_realtime(runner, g.clock))
            undo.append(functools.partial(_cancel, task))

    def stop() -> None:
        for fn in reversed(undo):
            fn()

    return stop


def _step(sg: SimGripper, clock: ManualClock, end: float, runner: ScenarioRunner | None) -> float:
    """Advance to ``end`` through every due time in between (device events, scenario actions)."""
    return _step_all([(sg, runner)], clock, end)


def _step_all(cell: list[tuple[SimGripper, ScenarioRunner | None]], clock: ManualClock, end: float) -> float:
    """Advance the grippers sharing ``clock`` to ``end`` through every due time of any of them."""
    for _ in range(1_000_000):  # bounded: a due time that never moves cannot spin forever
        t = end
        for sg, runner in cell:
            due = sg.gripper.next_due()
            if due is not None and due < t:
                t = max(due, clock.now)
            nt = runner.next_time() if runner is not None else None
            if nt is not None and nt < t:
                t = max(nt, clock.now)
        clock.set(t)
        for sg, runner in cell:
            sg.runner.poll_now()
            if runner is not None:
                runner.run_due(t)
                runner.observe(t)
        if t >= end:
            break
    return clock.now


IDLE_STEP = 0.05
"""Seconds a manual clock moves on while a replayed request waits for its reply."""


class CellGripper:
    """One gripper of a :class:`SimThread` (``sim[i]``): its addresses and its world."""

    def __init__(self, host: SimThread, index: int) -> None:
        self.index = index
        self.sim_gripper: SimGripper = host.sim.grippers[index]
        self.world = World(host, index)

    @property
    def url(self) -> str:
        """``tcp://127.0.0.1:PORT`` of this gripper."""
        url = self.sim_gripper.tcp_url
        if url is None:
            raise RuntimeError("TCP is off (tcp_port=None)")
        return url

    @property
    def udp_url(self) -> str:
        url = self.sim_gripper.udp_url
        if url is None:
            raise RuntimeError("UDP is off (udp_port=None)")
        return url

    @property
    def gripper(self) -> Any:
        """The :class:`~pywsg.device.VirtualGripper` (touch it only through ``SimThread.call``)."""
        return self.sim_gripper.gripper

    def __repr__(self) -> str:
        return f"<gripper {self.index} {self.sim_gripper.tcp_url or self.sim_gripper.udp_url}>"


class SimThread:
    """A :class:`~pywsg.server.SimServer` on a background loop; ``with SimThread(...) as sim``.

    Keyword arguments are :class:`~pywsg.server.SimOptions` fields (ports: 0 any free port, None off;
    default TCP and UDP on free loopback ports, UDP replies to the sender's port), plus

    - ``settings``: a settings file (Path), a :class:`~pywsg.device.Settings`, or a dict of its
      fields (``{"crc_check": False}``) applied to the defaults;
    - ``clock="manual"``: a :class:`~pywsg.device.ManualClock` (time moves only with
      ``world.advance(dt)``); a clock object is taken as it is; default real time;
    - ``time_scale=K``: real time run K times faster (:class:`~pywsg.device.ScaledClock`): motion,
      homing, heat, auto-update periods and scenarios; the network and client timeouts are not scaled;
    - ``count=N``: a cell of N grippers, each with its own world (``sim[i].url``, ``sim[i].world``);
    - ``scenario``: a TOML file or :class:`~pywsg.testing.scenario.Scenario` run on every gripper;
    - ``loop``: a shared :class:`LoopThread` (default: one of its own, closed by :meth:`stop`).
    """

    save_on_stop = True

    def __init__(self, options: SimOptions | None = None, *, loop: LoopThread | None = None,
                 scenario: str | Path | Scenario | None = None, **overrides: Any) -> None:
        settings = overrides.get("settings")
        if isinstance(settings, dict | Settings):
            overrides["settings"] = None
            overrides["factory"] = _settings_factory(settings)
        clock = overrides.get("clock")
        scale = overrides.pop("time_scale", None)
        if scale is not None:
            if clock is not None:
                raise ValueError("time_scale and clock: give one (the manual clock has no time scale)")
            if isinstance(scale, bool) or not isinstance(scale, int | float) or not 0 < scale < float("inf"):
                raise ValueError(f"time_scale: must be a positive number, not {scale!r}")
            overrides["clock"] = clock = ScaledClock(scale) if scale != 1 else None
        if clock == "manual":
            overrides["clock"] = ManualClock()
        elif isinstance(clock, str):
            raise ValueError(f"clock: 'manual' or a clock object, not {clock!r}")
        self.options = SimOptions(**overrides) if options is None else SimOptions(**{**options.__dict__, **overrides})
        self.clock: ManualClock | None = (self.options.clock if isinstance(self.options.clock, ManualClock)
                                          else None)
        self.scenario = Scenario.load(scenario) if isinstance(scenario, str | Path) else scenario
        self.scenario_runners: dict[int, ScenarioRunner] = {}
        self._own_loop = loop is None
        self._loop_thread = loop
        self.sim = SimServer(self.options)
        self._undo: list[Callable[[], None]] = []
        self.world = World(self)

    @property
    def loop(self) -> asyncio.AbstractEventLoop:
        assert self._loop_thread is not None, "not started"
        return self._loop_thread.loop

    def start(self: S) -> S:
        if self._loop_thread is None:
            self._loop_thread = LoopThread()
        try:
            # generous: the first start in a process imports the web stack (seconds on a loaded machine)
            self.run(self._start(), timeout=60)
        except BaseException:
            if self._own_loop:
                self._loop_thread.close()
            raise
        return self

    async def _start(self) -> None:
        await self.sim.start()
        self._undo.append(setup_world(self.sim, scenario=self.scenario, runners=self.scenario_runners,
                                      realtime=self.clock is None))

    def run(self, coro: Coroutine[Any, Any, T], timeout: float | None = 10) -> T:
        """Run ``coro`` on the server's loop and return its result."""
        assert self._loop_thread is not None, "not started"
        return self._loop_thread.run(coro, timeout)

    def call(self, fn: Callable[[], T], timeout: float | None = 10) -> T:
        """Run ``fn()`` on the server's loop thread (device state is touched only there)."""
        assert self._loop_thread is not None, "not started"
        return self._loop_thread.call(fn, timeout)

    async def _stop(self) -> None:
        for undo in self._undo:
            undo()
        await self.sim.close(save=self.save_on_stop)

    def stop(self) -> None:
        """Close every interface (and the loop thread, unless it was shared)."""
        if self._loop_thread is None:
            return
        try:
            self.run(self._stop())
        finally:
            if self._own_loop:
                self._loop_thread.close()
            self._loop_thread = None

    def __enter__(self: S) -> S:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    # -- the cell --------------------------------------------------------------------------------
    @property
    def grippers(self) -> list[CellGripper]:
        """Every gripper of this sim (``count=N``), each with its addresses and its own world."""
        return [CellGripper(self, i) for i in range(len(self.sim.grippers))]

    def __getitem__(self, i: int) -> CellGripper:
        return CellGripper(self, range(len(self.sim.grippers))[i])

    def __len__(self) -> int:
        return len(self.sim.grippers)

    # -- record once, test forever ---------------------------------------------------------------
    def replay(self, recording: str | Path, tolerance: float = 0.5, timeout: float = 10.0,
               index: int = 0, udp: bool = False) -> ReplayReport:
        """Replay the client side of ``recording`` (``wsg proxy --pcap/--jsonl``, Wireshark) against
        gripper ``index`` and compare the replies (:func:`pywsg.testing.replay.replay`). On a manual
        clock, time moves on by itself while a reply is awaited (a motion's final reply)."""
        sg = self.sim.grippers[index]
        url = sg.udp_url if udp else sg.tcp_url
        if url is None:
            raise RuntimeError(f"gripper {index}: {'UDP' if udp else 'TCP'} is off")
        idle = None
        if self.clock is not None:
            world = World(self, index)

            def idle() -> None:
                world.advance(IDLE_STEP)

        return replay(recording, url, tolerance, timeout, idle=idle)

    def assert_replays(self, recording: str | Path, tolerance: float = 0.5, timeout: float = 10.0,
                       index: int = 0, udp: bool = False) -> ReplayReport:
        """:meth:`replay`, then fail (AssertionError listing every difference) unless all replies matched::

            def test_field_session(wsg_sim):
                wsg_sim.assert_replays("captures/line3-monday.pcapng")
        """
        report = self.replay(recording, tolerance, timeout, index, udp)
        if not report.matched:
            lines = "\n".join(d.line() for d in report.differences)
            raise AssertionError(f"{recording}: {len(report.differences)} difference(s) from the recording "
                                 f"({report.steps} request(s)):\n{lines}")
        return report

    # -- addresses of gripper 0 ----------------------------------------------------------------
    @property
    def g(self) -> SimGripper:
        """Gripper 0's :class:`~pywsg.server.sim.SimGripper` (ports, runner, device)."""
        return self._sg

    @property
    def _sg(self) -> SimGripper:
        return self.sim.grippers[0]

    @property
    def gripper(self) -> Any:
        """Gripper 0's :class:`~pywsg.device.VirtualGripper` (touch it only through :meth:`call`)."""
        return self.sim.grippers[0].gripper

    @property
    def url(self) -> str:
        """``tcp://127.0.0.1:PORT`` for :class:`pywsg.client.Gripper` and ``wsg --url``."""
        url = self._sg.tcp_url
        if url is None:
            raise RuntimeError("TCP is off (tcp_port=None)")
        return url

    @property
    def udp_url(self) -> str:
        url = self._sg.udp_url
        if url is None:
            raise RuntimeError("UDP is off (udp_port=None)")
        return url

    @property
    def serial_url(self) -> str:
        """``serial:///dev/pts/N``: a pseudo-terminal, opened on first use."""
        sg = self._sg
        if sg.serial is None:
            from ..server.serial_port import SerialServer

            opts = self.options

            async def _open() -> None:
                sg.serial = await SerialServer(sg.gripper, sg.runner, "pty", opts.baudrate, opts.limits).start()

            self.run(_open())
        url = sg.serial_url
        assert url is not None
        return url

    @property
    def modbus_port(self) -> int:
        """The Modbus/TCP fieldbus port on 127.0.0.1, started on first use."""
        sg = self._sg
        if sg.modbus is None:
            from ..fieldbus.modbus.server import serve_modbus

            async def _open() -> None:
                sg.modbus = await serve_modbus(sg.gripper, sg.host, 0)
                sg.modbus_port = sg.modbus.port

            self.run(_open())
        assert sg.modbus_port is not None
        return sg.modbus_port
