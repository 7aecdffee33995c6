"""``wsg replay``: send a recorded client's requests to a gripper and report where the replies differ."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import click


@click.command("replay")
@click.argument("recording", type=click.Path(exists=True, dir_okay=False, path_type=Path))
@click.option("--to", "url", default=None, metavar="URL", help="The gripper: tcp://HOST[:1000] or udp://HOST[:1500].")
@click.option("--sim", "sim_model", default=None, metavar="MODEL",
              type=click.Choice(["wsg50", "wsg32", "wsg25", "wsg70"]),
              help="Instead of --to: a fresh virtual gripper of MODEL in this process, on a manual clock "
                   "(a motion's final reply comes at once): the CI one-liner.")
@click.option("--tolerance", type=float, default=0.5, show_default=True,
              help="Largest accepted difference of a measured value, in its unit (mm, mm/s, N, °C).")
@click.option("--timeout", type=float, default=10.0, show_default=True,
              help="Longest wait for one request's replies (s), a motion's final reply included.")
@click.option("--json", "as_json", is_flag=True, help="Print the report as JSON.")
@click.pass_context
def replay(ctx: click.Context, recording: Path, url: str | None, sim_model: str | None, tolerance: float,
           timeout: float, as_json: bool) -> None:
    """Replay the client side of RECORDING against a gripper and compare the replies.

    RECORDING: a pcap/pcapng capture (wsg proxy --pcap, Wireshark) or JSON lines (wsg proxy --jsonl,
    wsg --log-file). IDs, status codes and payload layouts must match exactly; measured values within
    --tolerance. Exit status 0 when everything matched, 1 when replies differ, 2 on bad input.

    \b
    Example: compare a real gripper's answers with the virtual one's
      wsg proxy --listen 2000 --to tcp://192.168.1.20:1000 --pcap real.pcapng   # record a session
      wsg replay real.pcapng --to tcp://127.0.0.1:1000                          # against wsg sim
      wsg replay real.pcapng --sim wsg50                                        # in CI, no sim to start
    """
    from ..testing.replay import replay as run

    as_json = as_json or (isinstance(ctx.obj, dict) and bool(ctx.obj.get("json")))
    if (url is None) == (sim_model is None):
        raise click.UsageError("give the gripper: --to URL or --sim MODEL (one of them)")
    try:
        if sim_model is not None:
            from ..testing.host import SimThread

            with SimThread(model=sim_model, clock="manual", udp_port=None) as sim:
                report = sim.replay(recording, tolerance, timeout)
        else:
            assert url is not None
            report = run(recording, url, tolerance, timeout)
    except ValueError as exc:
        raise click.UsageError(str(exc)) from None
    except OSError as exc:
        raise click.ClickException(f"cannot reach {url}: {exc.strerror or exc}") from None
    if as_json:
        click.echo(json.dumps(report.to_json(), ensure_ascii=False, default=str))
    else:
        for d in report.differences:
            click.echo(d.line())
        verdict = "all replies matched" if report.matched else f"{len(report.differences)} difference(s)"
        click.echo(f"{report.steps} request(s), {report.replies} reply frame(s): {verdict}")
    sys.exit(0 if report.matched else 1)
