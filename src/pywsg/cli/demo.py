"""``wsg demo``: the main job — a virtual WSG with its web interface, and gripping cycles against it.

It starts a virtual gripper (TCP command interface, web interface, Modbus/TCP), places a part
between its fingers, and drives it over real TCP with the asyncio driver through the manual's
gripping cycle: home, pre-position, grip, hold, release, back to start. Every step is printed with
its duration and the gripper's state; afterwards the gripper keeps serving (Ctrl-C stops it) so you
can watch it in the browser, connect other clients, or run ``wsg plc-demo`` against its Modbus port.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import signal
import time
from typing import Any

import click

from ..client import AsyncGripper
from ..errors import WsgError
from ..protocol import GripperState
from .runner import EXIT_CONNECTION, PORT, count


@click.command()
@click.option("--cycles", default=3, show_default=True, type=click.IntRange(0), help="Gripping cycles to run.")
@click.option("--model", default="wsg50", show_default=True,
              type=click.Choice(["wsg50", "wsg32", "wsg25", "wsg70"]), help="Device profile.")
@click.option("--host", default="127.0.0.1", show_default=True, help="Address the virtual gripper binds.")
@click.option("--tcp-port", default="1000", show_default=True, type=PORT,
              help="TCP command interface port (0: any free port; the demo drives the gripper over it).")
@click.option("--web-port", default="8080", show_default=True, type=PORT,
              help="Web interface port (0: any free port, off: none).")
@click.option("--modbus-port", default="5020", show_default=True, type=PORT,
              help="Modbus/TCP port (0: any free port, off: none; the standard 502 needs root).")
@click.option("--part-width", default=30.0, show_default=True, type=click.FloatRange(0, min_open=True),
              help="Width of the part placed, mm.")
@click.option("--open-width", default=60.0, show_default=True, type=click.FloatRange(0, min_open=True),
              help="Pre-position width, mm.")
@click.option("--speed", default=100.0, show_default=True, type=click.FloatRange(0, min_open=True),
              help="Travel speed, mm/s (the gripper clamps it to its limits).")
@click.option("--force", default=40.0, show_default=True, type=click.FloatRange(0, min_open=True),
              help="Gripping force limit, N.")
@click.option("--hold", default=1.0, show_default=True, type=click.FloatRange(0), help="Seconds to hold the part.")
@click.option("--exit", "exit_after", is_flag=True, help="Stop after the cycles instead of serving on.")
@click.option("--json", "as_json", is_flag=True, help="One JSON object per step on stdout.")
@click.pass_context
def demo(ctx: click.Context, cycles: int, model: str, host: str, tcp_port: int | None, web_port: int | None,
         modbus_port: int | None, part_width: float, open_width: float, speed: float, force: float, hold: float,
         exit_after: bool, as_json: bool) -> None:
    """Run a virtual WSG with its web interface and drive gripping cycles against it.

    Widths in mm, speeds in mm/s, forces in N. Ctrl-C stops the virtual gripper.
    """
    from ..server.sim import SimError

    as_json = as_json or bool((ctx.obj or {}).get("json")) if isinstance(ctx.obj, dict) else as_json
    if tcp_port is None:
        raise click.BadParameter("the demo drives the gripper over TCP: give a port (0: any free port)",
                                 param_hint="--tcp-port")
    try:
        ok = asyncio.run(_demo(cycles=cycles, model=model, host=host, tcp_port=tcp_port, web_port=web_port,
                               modbus_port=modbus_port, part_width=part_width, open_width=open_width,
                               speed=speed, force=force, hold=hold, exit_after=exit_after, as_json=as_json))
    except (SimError, OSError) as exc:  # a port taken, an address not ours: say which, no traceback
        if as_json:
            _say(as_json, "error", "", error=str(exc))
        click.echo(f"error: {exc}", err=True)
        click.echo("hint: another `wsg sim`/`wsg demo` may be running; stop it, or pick other ports "
                   "(--tcp-port 0 --web-port 0 --modbus-port 0: any free ones)", err=True)
        raise SystemExit(EXIT_CONNECTION) from None
    raise SystemExit(0 if ok else 1)


def _say(as_json: bool, event: str, text: str, **data: Any) -> None:
    if as_json:
        click.echo(json.dumps({"event": event, **data}), nl=True)
    else:
        click.echo(text)


async def _demo(*, cycles: int, model: str, host: str, tcp_port: int, web_port: int | None,
                modbus_port: int | None,
                part_width: float, open_width: float, speed: float, force: float, hold: float,
                exit_after: bool, as_json: bool) -> bool:
    from ..server import SimServer

    async with SimServer(model=model, host=host, tcp_port=tcp_port, udp_port=None, web_port=web_port,
                         modbus_port=modbus_port) as sim:
        g0 = sim.grippers[0]
        _say(as_json, "started", f"virtual {model.upper()} running:", model=model)
        _say(as_json, "interface", f"  TCP command interface  {g0.tcp_url}", kind="tcp", url=g0.tcp_url)
        if sim.web_port:
            url = f"http://{host}:{sim.web_port}/"
            _say(as_json, "interface", f"  web interface          {url}", kind="web", url=url)
        if sim.modbus_port:
            _say(as_json, "interface", f"  Modbus/TCP             {host}:{sim.modbus_port}", kind="modbus",
                 port=sim.modbus_port)
        faults = g0.gripper.faults  # type: ignore[attr-defined]
        assert g0.tcp_url is not None  # the TCP interface is always on in the demo
        ok = await _cycles(g0.tcp_url, cycles, part_width, open_width, speed, force, hold, as_json, faults)
        if exit_after:
            return ok
        _say(as_json, "serving", "serving on; Ctrl-C stops the virtual gripper")
        stop = asyncio.Event()
        loop = asyncio.get_running_loop()
        for sig in (signal.SIGINT, signal.SIGTERM):
            with contextlib.suppress(NotImplementedError):
                loop.add_signal_handler(sig, stop.set)
        await stop.wait()
        return ok


async def _after(seconds: float, coro: Any) -> Any:
    """Await ``coro`` after ``seconds`` s (a step whose printed time includes the wait)."""
    await asyncio.sleep(seconds)
    return await coro


async def _cycles(url: str, cycles: int, part: float, open_width: float, speed: float, force: float,
                  hold: float, as_json: bool, faults: Any) -> bool:
    """The gripping cycle over TCP. ``faults`` is the virtual gripper's fault-injection API: it plays
    the robot that brings each part between the fingers and takes it away after the release."""
    async with AsyncGripper(url) as g:
        await g.connect()

        async def step(name: str, coro: Any) -> None:
            t0 = time.perf_counter()
            await coro
            st = await g.state()
            dt = time.perf_counter() - t0
            state = st.gripper_state.name if isinstance(st.gripper_state, GripperState) else st.gripper_state
            _say(as_json, "step", f"  {name:<28} {dt:6.2f} s   width {st.width:6.2f} mm   force {st.force:5.1f} N"
                 f"   {state}", step=name, seconds=round(dt, 3), width=round(st.width, 3),
                 force=round(st.force, 3), state=state)

        try:
            await step("homing", g.home())
            start = await g.width()
            for n in range(1, cycles + 1):
                _say(as_json, "cycle", f"cycle {n}/{cycles}", cycle=n)
                faults.place_part(part)
                _say(as_json, "part", f"  (a {part:g} mm part is placed between the fingers)", width=part)
                await step(f"pre-position to {open_width:g} mm", g.move(open_width, speed))
                await step(f"grip {part:g} mm part at {force:g} N", g.grip(part, speed, force=force))
                await step(f"hold {hold:g} s", _after(hold, g.gripper_state()))
                await step(f"release to {open_width:g} mm", g.release(open_width, speed))
                faults.remove_part()
                _say(as_json, "part", "  (the part is taken away)")
                await step(f"back to start ({start:g} mm)", g.move(start, speed))
            stats = await g.statistics()
            _say(as_json, "statistics", f"gripping statistics: {count(stats.total, 'grip')}, {stats.no_part} no part, "
                 f"{stats.lost_part} lost", total=stats.total, no_part=stats.no_part, lost_part=stats.lost_part)
        except WsgError as exc:
            _say(as_json, "error", f"error: {exc}", error=str(exc))
            return False
    return True
