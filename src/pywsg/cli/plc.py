"""``wsg plc-demo``: the fieldbus manual's SCL gripping cycle (002 Appendix D) as a Python soft PLC.

Connects to a gripper's fieldbus interface over any bus (``--url``: Modbus/TCP to a real WSG on
port 502 or ``wsg sim --modbus-port N``; PROFINET; PROFIBUS) and runs
:class:`pywsg.fieldbus.plc.GrippingCycle` once per scan,
printing every step: homing, pre-position, grip, hold 1 s, release, back to start; on an error
(gripper state ERROR, or a refused command) STOP/ACK and homing again, as the listing does.
"""

from __future__ import annotations

import asyncio
import contextlib
import dataclasses
import json
import sys
import time
from collections.abc import AsyncIterator, Callable
from dataclasses import dataclass
from typing import Any

import click

from ..fieldbus.exchange import SCHEMES, URL_FORMS, FieldbusConnectionError, scheme_of
from ..fieldbus.image import CmdFlag, OutputImage
from ..fieldbus.plc import AsyncFieldbusGripper, GrippingCycle
from ..protocol import GState
from .runner import EXIT_CONNECTION, count


@dataclass
class DemoResult:
    """What a demo run did."""

    cycles: int
    holds: int
    no_part: int
    errors: int
    fast_stops_injected: int
    completed: bool


async def run_demo(url: str, cycles: int = 3, *, scan: float = 0.002, timeout: float = 60.0,
                   fast_stop_cycle: int | None = None, model: str = "wsg50",
                   echo: Callable[[str], None] = print, recover_fast_stop: bool = False) -> DemoResult:
    """Run the gripping cycle over the bus ``url`` names until ``cycles`` cycles are done (or
    ``timeout`` s pass).

    ``fast_stop_cycle``: in that cycle (1-based) raise FASTSTOP for one scan while the fingers move,
    to show the listing's error path (STOP/ACK, homing, restart). ``recover_fast_stop``: see
    :class:`GrippingCycle` (off: the listing exactly).
    """
    plc = await AsyncFieldbusGripper.open_url(url, model=model)
    cyc = GrippingCycle(log=echo, recover_fast_stop=recover_fast_stop)
    inputs = None
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
    hint = None if completed or inputs is None else cyc.fast_stop_hint(inputs)
    if hint:
        echo(f"stuck in {hint}")
    echo(f"done: {count(cyc.cycles, 'cycle')}, {count(cyc.holds, 'part')} held, {cyc.no_part} without part, "
         f"{count(cyc.error_count, 'error recovery', 'error recoveries')}"
         + ("" if completed else f" — timed out after {timeout:g} s"))
    if scheme_of(url) == "profibus":   # the master went offline: say what the slave does now
        from ..fieldbus.profibus.master import offline_note

        echo(offline_note(url))
    return DemoResult(cyc.cycles, cyc.holds, cyc.no_part, cyc.error_count, injected, completed)


@contextlib.asynccontextmanager
async def _local_sim(model: str, part_width: float | None) -> AsyncIterator[str]:
    """An in-process virtual gripper with Modbus/TCP on a free port; yields its URL."""
    from ..server import SimServer

    async with SimServer(model=model, tcp_port=None, udp_port=None, modbus_port=0) as sim:
        gripper: Any = sim.grippers[0].gripper
        if part_width is not None:
            gripper.faults.place_part(part_width)
        assert sim.modbus_port is not None
        yield f"modbus-tcp://127.0.0.1:{sim.modbus_port}"


def _connection_message(exc: OSError, where: str) -> str:
    """One line for a failed or lost bus connection, with a hint where none is given yet."""
    text = str(exc) if isinstance(exc, FieldbusConnectionError) else f"no connection to {where}: {exc}"
    if "(is " in text or "pip install" in text or "has no" in text:   # already says what to do
        return text
    if where.startswith("modbus"):
        return f"{text} (is the gripper, or `wsg sim --modbus-port N`, running?)"
    return f"{text} (is the gripper running and its bus enabled?)"


MODELS = ("wsg50", "wsg32", "wsg25", "wsg70")
DEFAULT_URL = "modbus-tcp://127.0.0.1:502"


def check_url(url: str) -> str:
    """The bus URL, checked as far as it can be without opening it (a bare ``HOST[:PORT]`` is
    Modbus/TCP); click.BadParameter says what is wrong."""
    try:
        scheme = scheme_of(url)
        if SCHEMES[scheme] == "modbus":
            from ..fieldbus.modbus.exchange import parse_url

            host, port = parse_url(url)
            return f"modbus-tcp://{host}:{port}"
        if SCHEMES[scheme] == "profinet":
            from ..fieldbus.profinet.exchange import ProfinetUrl

            ProfinetUrl.parse(url)
    except ValueError as exc:
        raise click.BadParameter(str(exc), param_hint="--url") from None
    return url


@click.command("plc-demo")
@click.option("--url", default=None, metavar="URL",
              help=f"The gripper's fieldbus interface: {URL_FORMS} (default {DEFAULT_URL}; "
              "`wsg sim --modbus-port 5020` prints modbus-tcp://127.0.0.1:5020).")
@click.option("--host", default=None, hidden=True, help="Deprecated: use --url modbus-tcp://HOST:PORT.")
@click.option("--port", default=None, type=click.IntRange(1, 65535), hidden=True,
              help="Deprecated: use --url modbus-tcp://HOST:PORT.")
@click.option("--cycles", default=3, show_default=True, type=click.IntRange(1), help="Gripping cycles to run.")
@click.option("--model", default="wsg50", show_default=True, type=click.Choice(MODELS),
              help="Gripper model (force unit: 1/10 N on wsg70).")
@click.option("--scan", default=2.0, show_default=True, type=click.FloatRange(0, min_open=True), metavar="MS",
              help="PLC scan time in ms.")
@click.option("--timeout", default=60.0, show_default=True, type=click.FloatRange(0, min_open=True),
              metavar="SECONDS", help="Give up after this many seconds (exit 1).")
@click.option("--fast-stop-cycle", type=click.IntRange(1), default=None, metavar="N",
              help="Fault: raise FASTSTOP while the fingers move in cycle N (shows the error path).")
@click.option("--recover-fast-stop", is_flag=True,
              help="Not in the listing: go to its error step (STOP/ACK, homing) on SYSSTATE.FAST_STOP as on ERROR; "
              "without it a FAST STOP during a grip leaves the cycle waiting until --timeout (002 §4.6: IDLE).")
@click.option("--sim", "local_sim", is_flag=True,
              help="Run against an in-process virtual gripper instead of --url.")
@click.option("--part-width", default=22.0, show_default=True, type=click.FloatRange(0, min_open=True),
              help="With --sim: width of the part in the fingers, mm.")
@click.option("--no-part", is_flag=True, help="With --sim: no part, so GRIP ends in NO_PART and the cycle "
              "releases at once.")
@click.option("--json", "as_json", is_flag=True,
              help='One JSON object per line: {"event": "step", "text": ...}, then {"event": "done", ...}.')
@click.pass_context
def plc_demo(ctx: click.Context, url: str | None, host: str | None, port: int | None, cycles: int, model: str,
             scan: float, timeout: float, fast_stop_cycle: int | None, recover_fast_stop: bool, local_sim: bool,
             part_width: float, no_part: bool, as_json: bool) -> None:
    """Run the fieldbus manual's gripping-cycle demo (002 Appendix D, SCL) over a fieldbus.

    Homing, pre-position to 30 mm, grip at 22 mm with 50 N, hold 1 s, release to 30 mm, back to
    60 mm, and again; on an error STOP/ACK and homing.

    \b
    Start a gripper first, then run the demo against its Modbus/TCP port:
      wsg sim --modbus-port 5020
      wsg plc-demo --url modbus-tcp://127.0.0.1:5020
    or use --sim for an in-process virtual gripper. PROFINET and PROFIBUS masters take
    --url profinet://IFACE/STATION and --url profibus://PORT?address=N&baudrate=B.

    Exit status: 0 all cycles done, 1 timed out, 2 usage error, 3 no connection.
    """
    as_json = as_json or bool((ctx.obj or {}).get("json")) if isinstance(ctx.obj, dict) else as_json
    if no_part and not local_sim:
        raise click.UsageError("--no-part needs --sim (over the bus a PLC cannot take the part away); "
                               "start wsg sim without a part instead")
    if host is not None or port is not None:
        if url is not None:
            raise click.UsageError("give --url, or the deprecated --host/--port, not both")
        click.echo("warning: --host/--port are deprecated; use --url modbus-tcp://HOST:PORT", err=True)
        url = f"modbus-tcp://{host or '127.0.0.1'}:{port or 502}"
    target = check_url(url or DEFAULT_URL)

    def echo(text: str) -> None:
        click.echo(json.dumps({"event": "step", "text": text}, ensure_ascii=False) if as_json else text)

    async def main() -> DemoResult:
        if local_sim:
            async with _local_sim(model, None if no_part else part_width) as sim_url:
                if as_json:
                    click.echo(json.dumps({"event": "started", "url": sim_url}))
                else:
                    click.echo(f"in-process virtual {model} with Modbus/TCP on {sim_url.removeprefix('modbus-tcp://')}")
                return await run_demo(sim_url, cycles, scan=scan / 1000, timeout=timeout,
                                      fast_stop_cycle=fast_stop_cycle, model=model, echo=echo,
                                      recover_fast_stop=recover_fast_stop)
        return await run_demo(target, cycles, scan=scan / 1000, timeout=timeout,
                              fast_stop_cycle=fast_stop_cycle, model=model, echo=echo,
                              recover_fast_stop=recover_fast_stop)

    try:
        result = asyncio.run(main())
    except (ConnectionError, OSError) as exc:
        where = "the in-process virtual gripper" if local_sim else target
        message = _connection_message(exc, where)
        if as_json:
            click.echo(json.dumps({"event": "error", "ok": False, "error": message}))
        click.echo(f"error: {message}", err=True)
        sys.exit(EXIT_CONNECTION)
    if as_json:
        click.echo(json.dumps({"event": "done", "ok": result.completed, **dataclasses.asdict(result)}))
    sys.exit(0 if result.completed else 1)
