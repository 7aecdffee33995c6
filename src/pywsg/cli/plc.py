"""``wsg plc-demo``: the fieldbus manual's SCL gripping cycle (002 Appendix D) as a Python soft PLC.

Connects to a gripper's Modbus/TCP fieldbus interface (a real WSG on port 502, or
``wsg sim --modbus-port N``) and runs :class:`pywsg.fieldbus.plc.GrippingCycle` once per scan,
printing every step: homing, pre-position, grip, hold 1 s, release, back to start; on an error
(gripper state ERROR, or a refused command) STOP/ACK and homing again, as the listing does.
"""

from __future__ import annotations

import asyncio
import contextlib
import sys
import time
from collections.abc import AsyncIterator, Callable
from dataclasses import dataclass
from typing import Any

import click

from ..fieldbus.image import CmdFlag, OutputImage
from ..fieldbus.plc import AsyncFieldbusGripper, GrippingCycle
from ..protocol import GState


@dataclass
class DemoResult:
    """What a demo run did."""

    cycles: int
    holds: int
    no_part: int
    errors: int
    fast_stops_injected: int
    completed: bool


async def run_demo(host: str, port: int, cycles: int = 3, *, scan: float = 0.002, timeout: float = 60.0,
                   fast_stop_cycle: int | None = None, model: str = "wsg50",
                   echo: Callable[[str], None] = print) -> DemoResult:
    """Run the gripping cycle until ``cycles`` cycles are done (or ``timeout`` s pass).

    ``fast_stop_cycle``: in that cycle (1-based) raise FASTSTOP for one scan while the fingers move,
    to show the listing's error path (STOP/ACK, homing, restart).
    """
    plc = await AsyncFieldbusGripper.open(host, port, model=model)
    cyc = GrippingCycle(log=echo)
    injected = 0
    deadline = time.monotonic() + timeout
    done_cycles = -1
    try:
        await plc.write(OutputImage(if_flags=plc.outputs.if_flags))   # defined start: no command flags
        while cyc.cycles < cycles and time.monotonic() < deadline:
            inputs = await plc.read()
            if cyc.cycles != done_cycles:
                done_cycles = cyc.cycles
                if done_cycles < cycles:
                    echo(f"--- cycle {done_cycles + 1} of {cycles} ---")
            out = cyc.step(inputs, time.monotonic())
            if (fast_stop_cycle is not None and not injected and cyc.cycles + 1 == fast_stop_cycle
                    and inputs.gstate & (GState.POSITIONING | GState.GRIPPING) and cyc.state >= 3):
                injected += 1
                echo("!!! injected fault: FASTSTOP raised while the fingers move")
                out = OutputImage(out.cmdflags | CmdFlag.FASTSTOP, out.if_flags, out.width, out.speed,
                                  out.force_limit)
            if out != plc.outputs:
                await plc.write(out)
            await asyncio.sleep(scan)
        await plc.write(OutputImage(if_flags=plc.outputs.if_flags))   # leave no flag raised
    finally:
        await plc.close()
    completed = cyc.cycles >= cycles
    echo(f"done: {cyc.cycles} cycle(s), {cyc.holds} part(s) held, {cyc.no_part} without part, "
         f"{cyc.error_count} error recovery(ies)" + ("" if completed else f" — timed out after {timeout:g} s"))
    return DemoResult(cyc.cycles, cyc.holds, cyc.no_part, cyc.error_count, injected, completed)


@contextlib.asynccontextmanager
async def _local_sim(model: str, part_width: float | None) -> AsyncIterator[int]:
    """An in-process virtual gripper with Modbus/TCP on a free port; yields the port."""
    from ..server import SimServer

    async with SimServer(model=model, tcp_port=None, udp_port=None, modbus_port=0) as sim:
        gripper: Any = sim.grippers[0].gripper
        if part_width is not None:
            gripper.faults.place_part(part_width)
        assert sim.modbus_port is not None
        yield sim.modbus_port


@click.command("plc-demo")
@click.option("--host", default="127.0.0.1", show_default=True, help="Gripper (or wsg sim) address.")
@click.option("--port", default=502, show_default=True, type=int, help="Modbus/TCP port (wsg sim --modbus-port).")
@click.option("--cycles", default=3, show_default=True, type=int, help="Gripping cycles to run.")
@click.option("--model", default="wsg50", show_default=True, help="Gripper model (force unit: 1/10 N on wsg70).")
@click.option("--scan", default=2.0, show_default=True, type=float, help="PLC scan time in ms.")
@click.option("--timeout", default=60.0, show_default=True, type=float, help="Give up after this many seconds.")
@click.option("--fast-stop-cycle", type=int, default=None, metavar="N",
              help="Fault: raise FASTSTOP while the fingers move in cycle N (shows the error path).")
@click.option("--sim", "local_sim", is_flag=True,
              help="Run against an in-process virtual gripper instead of --host/--port.")
@click.option("--part-width", default=22.0, show_default=True, type=float,
              help="With --sim: width of the part in the fingers, mm.")
@click.option("--no-part", is_flag=True, help="With --sim: no part, so GRIP ends in NO_PART and the cycle "
              "releases at once.")
def plc_demo(host: str, port: int, cycles: int, model: str, scan: float, timeout: float,
             fast_stop_cycle: int | None, local_sim: bool, part_width: float, no_part: bool) -> None:
    """Run the fieldbus manual's gripping-cycle demo (SCL, Appendix D) over Modbus/TCP.

    Homing, pre-position to 30 mm, grip at 22 mm with 50 N, hold 1 s, release to 30 mm, back to
    60 mm, and again; on an error STOP/ACK and homing. Start a gripper first, e.g.
    ``wsg sim --modbus-port 5020`` then ``wsg plc-demo --port 5020``, or use ``--sim``.
    """
    if no_part and not local_sim:
        raise click.UsageError("--no-part needs --sim (over the bus a PLC cannot take the part away); "
                               "start wsg sim without a part instead")

    async def main() -> DemoResult:
        if local_sim:
            async with _local_sim(model, None if no_part else part_width) as sim_port:
                click.echo(f"in-process virtual {model} with Modbus/TCP on 127.0.0.1:{sim_port}")
                return await run_demo("127.0.0.1", sim_port, cycles, scan=scan / 1000, timeout=timeout,
                                      fast_stop_cycle=fast_stop_cycle, model=model, echo=click.echo)
        return await run_demo(host, port, cycles, scan=scan / 1000, timeout=timeout,
                              fast_stop_cycle=fast_stop_cycle, model=model, echo=click.echo)

    try:
        result = asyncio.run(main())
    except ConnectionError as exc:
        raise click.ClickException(f"{exc} (is the gripper or `wsg sim --modbus-port N` running?)") from exc
    sys.exit(0 if result.completed else 1)
