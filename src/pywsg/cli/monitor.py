"""``wsg monitor``: a live view of the gripper from auto-update streams (rich ``Live``).

Width, speed and force (43h/44h/45h), gripper state (41h) and system flags (40h) arrive as
auto-update packets at ``--period``; the temperature (46h, no auto-update) is polled once a
second. Width and force get a small sparkline of the last samples. Keys: ``s`` stop (22h),
``a`` acknowledge FAST STOP (24h), ``f`` FAST STOP (23h), ``q`` (or Ctrl-C) quit.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import os
import sys
import time
from collections import deque
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any

import click

from . import signals
from .runner import Options, common_options, fail, jsonable, options

BARS = "▁▂▃▄▅▆▇█"
STREAMS = ("width", "speed", "force", "gripper_state", "system_state")
KEYS = {"s": ("stop", "stop"), "a": ("acknowledge", "ack"), "f": ("fast_stop", "fast-stop")}


def sparkline(values: list[float], lo: float | None = None, hi: float | None = None) -> str:
    """``▁▂▄█``-style line for ``values`` scaled to [lo, hi] (default: their own range)."""
    if not values:
        return ""
    lo = min(values) if lo is None else lo
    hi = max(values) if hi is None else hi
    span = hi - lo
    if span <= 0:
        return BARS[0] * len(values)
    top = len(BARS) - 1
    return "".join(BARS[max(0, min(top, round((v - lo) / span * top)))] for v in values)


@dataclass
class View:
    """What the monitor shows; updated from stream callbacks."""

    width: float | None = None
    speed: float | None = None
    force: float | None = None
    gripper_state: Any = None
    system_state: Any = None
    temperature: float | None = None
    stroke: float | None = None
    max_force: float | None = None
    widths: deque[float] = field(default_factory=lambda: deque(maxlen=48))
    forces: deque[float] = field(default_factory=lambda: deque(maxlen=48))
    samples: int = 0
    message: str = ""
    started: float = field(default_factory=time.monotonic)

    def update(self, name: str, value: Any) -> None:
        setattr(self, name, value)
        self.samples += 1
        if name == "width":
            self.widths.append(float(value))
        elif name == "force":
            self.forces.append(float(value))

    def to_json(self) -> dict[str, Any]:
        return {"time": round(time.time(), 3), "width": self.width, "speed": self.speed, "force": self.force,
                "gripper_state": jsonable(self.gripper_state), "flags": jsonable(self.system_state),
                "temperature": self.temperature, "message": self.message or None}

    def render(self) -> Any:
        from rich.panel import Panel
        from rich.table import Table

        t = Table.grid(padding=(0, 2))
        t.add_column(justify="left", style="bold")
        t.add_column(justify="right")
        t.add_column(justify="left")

        def num(v: float | None, unit: str) -> str:
            return "—" if v is None else f"{v:8.2f} {unit}"

        t.add_row("Width", num(self.width, "mm"), sparkline(list(self.widths), 0.0, self.stroke))
        t.add_row("Speed", num(self.speed, "mm/s"), "")
        t.add_row("Force", num(self.force, "N"), sparkline(list(self.forces), 0.0, self.max_force))
        gs = self.gripper_state
        t.add_row("State", getattr(gs, "name", str(gs)) if gs is not None else "—", "")
        flags = jsonable(self.system_state) if self.system_state is not None else None
        t.add_row("Flags", f"0x{int(self.system_state):08X}" if self.system_state is not None else "—",
                  ", ".join(flags) if flags else "")
        t.add_row("Temp", num(self.temperature, "°C"), "")
        footer = "keys: [b]s[/b] stop  [b]a[/b] ack  [b]f[/b] fast stop  [b]q[/b] quit"
        if self.message:
            footer += f"   │ {self.message}"
        title = f"WSG monitor · {self.samples} samples"
        return Panel(t, title=title, subtitle=footer, expand=False)


@contextlib.contextmanager
def _cbreak() -> Iterator[bool]:
    """Single-key input without echo while the monitor runs (only on a terminal)."""
    if not sys.stdin.isatty():
        yield False
        return
    import termios
    import tty

    fd = sys.stdin.fileno()
    old = termios.tcgetattr(fd)
    try:
        tty.setcbreak(fd)
        yield True
    finally:
        termios.tcsetattr(fd, termios.TCSADRAIN, old)


async def _monitor(opts: Options, period: float, duration: float | None, refresh: float) -> int:
    from .gripper import _driver

    g = _driver()(opts.url, timeout=opts.timeout, connect_timeout=min(opts.timeout, 5.0))
    if opts.log is not None:
        g.on_frame = opts.log.hook
    await g.connect()
    view = View()
    quit_ev = asyncio.Event()
    loop = asyncio.get_running_loop()
    actions: set[asyncio.Task[None]] = set()

    async def press(key: str) -> None:
        method, label = KEYS[key]
        try:
            await getattr(g, method)()
            view.message = f"{label}: E_SUCCESS"
        except Exception as exc:
            view.message = f"{label}: {getattr(exc, 'status_name', type(exc).__name__)}"

    def on_key() -> None:
        for ch in os.read(0, 64).decode("utf-8", "ignore").lower():
            if ch == "q":
                quit_ev.set()
            elif ch in KEYS:
                task = loop.create_task(press(ch))
                actions.add(task)
                task.add_done_callback(actions.discard)

    try:
        lim = await g.limits()
        view.stroke, view.max_force = lim.stroke, lim.overdrive_force or lim.nominal_force
        streams = []
        for name in STREAMS:
            s = await g.subscribe(name, period, maxlen=1)
            s.callbacks.append(lambda sample, n=name: view.update(n, sample.value))
            streams.append(s)

        async def poll_temperature() -> None:
            while True:
                with contextlib.suppress(Exception):
                    view.temperature = await g.temperature()
                await asyncio.sleep(1.0)

        temp_task = loop.create_task(poll_temperature())
        deadline = None if duration is None else time.monotonic() + duration
        with _cbreak() as keys:
            if keys:
                loop.add_reader(0, on_key)
            try:
                if opts.as_json:
                    await _json_loop(view, quit_ev, deadline, refresh)
                else:
                    await _live_loop(view, quit_ev, deadline, refresh)
            finally:
                if keys:
                    loop.remove_reader(0)
        temp_task.cancel()
        with contextlib.suppress(asyncio.CancelledError):
            await temp_task
        for s in streams:
            await s.close()
    finally:
        await g.close()
    return 0


async def _wait(quit_ev: asyncio.Event, deadline: float | None, refresh: float) -> bool:
    """Sleep one refresh; True when it is time to leave."""
    timeout = refresh if deadline is None else max(0.0, min(refresh, deadline - time.monotonic()))
    with contextlib.suppress(asyncio.TimeoutError):
        await asyncio.wait_for(quit_ev.wait(), timeout)
    return quit_ev.is_set() or (deadline is not None and time.monotonic() >= deadline)


async def _live_loop(view: View, quit_ev: asyncio.Event, deadline: float | None, refresh: float) -> None:
    from rich.console import Console
    from rich.live import Live

    console = Console()
    with Live(view.render(), console=console, auto_refresh=False, transient=False) as live:
        while not await _wait(quit_ev, deadline, refresh):
            live.update(view.render(), refresh=True)
        live.update(view.render(), refresh=True)


async def _json_loop(view: View, quit_ev: asyncio.Event, deadline: float | None, refresh: float) -> None:
    while not await _wait(quit_ev, deadline, refresh):
        click.echo(json.dumps(view.to_json(), ensure_ascii=False))
    click.echo(json.dumps(view.to_json(), ensure_ascii=False))


@click.command("monitor")
@click.option("--period", type=click.IntRange(10, 65535), default=50, show_default=True, metavar="MS",
              help="Auto-update period of the streams in ms (the gripper's minimum is 10 ms).")
@click.option("--refresh", type=click.FloatRange(min=0.02), default=0.1, show_default=True, metavar="SECONDS",
              help="Screen refresh interval (with --json: one JSON line per interval).")
@click.option("--duration", type=click.FloatRange(min=0), default=None, metavar="SECONDS",
              help="Quit after this many seconds (default: run until q or Ctrl-C).")
@common_options
@click.pass_context
def monitor(ctx: click.Context, /, period: int, refresh: float, duration: float | None, **kw: Any) -> None:
    """Live view: width (mm), speed (mm/s), force (N), gripper state, system flags and temperature (°C),
    refreshed in place, with width and force sparklines.

    Keys: s stop (22h), a acknowledge a FAST STOP (24h), f FAST STOP (23h), q quit.
    With --json: one JSON object per refresh instead of the screen.
    """
    opts = options(ctx, kw.pop("as_json"), kw.pop("log_flag"), kw.pop("log_file"), kw.pop("timeout"))
    try:
        signals.run(_monitor(opts, period / 1000.0, duration, refresh))
    except Exception as exc:
        fail(exc, opts.as_json, opts.url)
