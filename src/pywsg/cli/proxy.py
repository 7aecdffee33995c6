"""``wsg proxy``: a transparent tap between any client and any WSG, with a decoded line per frame."""

from __future__ import annotations

import asyncio
import contextlib
import gc
import json
import signal
import sys
from pathlib import Path
from typing import Any, TextIO

import click

from .runner import FloatRange


def _open_jsonl(path: Path) -> TextIO:
    """The --jsonl file, opened for writing (the caller closes it); a path that cannot be written is
    a usage error naming --jsonl."""
    try:
        return open(path, "w", encoding="utf-8")   # the caller closes it
    except OSError as exc:
        raise click.BadParameter(f"cannot write {path}: {exc.strerror or exc}", param_hint="--jsonl") from None


@click.command("proxy")
@click.option("--listen", "listen", required=True, metavar="[HOST:]PORT",
              help="Where clients connect instead of the gripper (default host 127.0.0.1; 0: any free port).")
@click.option("--to", "target", required=True, metavar="URL",
              help="The gripper: tcp://HOST[:1000] or udp://HOST[:1500][?reply_port=1501].")
@click.option("--pcap", "pcap", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Write the exchange as pcapng (wsg decode -f, wsg replay, Wireshark read it).")
@click.option("--jsonl", "jsonl", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Write one JSON object per frame (wsg log and wsg replay read it).")
@click.option("--log-rate", type=click.IntRange(0, 10**6), default=1000, show_default=True, metavar="N",
              help="Frames a second at most in the printed/--jsonl log (0: all); one line a second says "
                   "what was left out. The --pcap file always has every byte.")
@click.option("--net", "net_faults", multiple=True, metavar="KIND[:K=V,...]",
              help="Start with a network fault between gripper and client (repeatable), e.g. latency:ms=200,jitter=50, "
                   "bandwidth:rate=500, slicer:size=1,gap=5, reset:timeout=2, silent, drop:p=0.3, reorder:p=0.5, "
                   "garble:p=0.01 (wsg world net --help).")
@click.option("--control", "control", default=None, metavar="[HOST:]PORT",
              help="Serve the network faults' control API here (0: any free port): "
                   "wsg world --sim http://127.0.0.1:PORT net latency --ms 200 switches them at runtime.")
@click.option("--udp-idle", type=FloatRange(0.1, 86400), default=60.0, show_default=True, metavar="S",
              help="UDP: close a client's upstream socket after S seconds without traffic.")
@click.option("--json", "as_json", is_flag=True, help="Print JSON lines instead of text lines.")
@click.option("-q", "--quiet", is_flag=True, help="Print nothing per frame (files only).")
@click.pass_context
def proxy(ctx: click.Context, listen: str, target: str, pcap: Path | None, jsonl: Path | None,
          log_rate: int, net_faults: tuple[str, ...], control: str | None, udp_idle: float, as_json: bool,
          quiet: bool) -> None:
    """Forward a client's traffic to a gripper unchanged and show every frame.

    Point your own client (ROS node, PLC, script) at the --listen port instead of the gripper. Bytes
    are forwarded unchanged and in order; each complete frame prints one line: time, TX (client to
    gripper) or RX, command ID and name, the raw bytes, status and decoded fields. The protocol
    (TCP or UDP) is the --to URL's. Stops on Ctrl-C or SIGTERM.

    \b
    Example:
      wsg proxy --listen 2000 --to tcp://192.168.1.20:1000 --pcap cell.pcapng
      wsg --url tcp://127.0.0.1:2000 home          # any client, through the tap
      wsg decode -f cell.pcapng                    # later: the whole exchange

    \b
    Network faults in front of a real gripper (the capture has the bytes as the gripper sent them):
      wsg proxy --listen 2000 --to tcp://192.168.1.20:1000 --net latency:ms=200 --control 8474
      wsg world --sim http://127.0.0.1:8474 net silent     # the gripper goes quiet, at once
      wsg world --sim http://127.0.0.1:8474 net clear
    """
    from ..capture.commlog import CommLog, LogEntry
    from ..server.netfault import NetFaults
    from ..testing.proxy import Proxy

    net = NetFaults()
    for spec in net_faults:
        start_fault(net, spec)
    control_addr = _address(control, "--control") if control is not None else None

    host, _, port_text = listen.rpartition(":")
    try:
        port = int(port_text)
        if not 0 <= port <= 65535:
            raise ValueError
    except ValueError:
        raise click.BadParameter(f"{listen!r}: give PORT or HOST:PORT", param_hint="--listen") from None
    as_json = as_json or bool((ctx.obj or {}).get("json")) if isinstance(ctx.obj, dict) else as_json
    jsonl_file = _open_jsonl(jsonl) if jsonl else None
    if quiet:
        log = CommLog(jsonl=jsonl_file)
    elif as_json:
        log = CommLog(jsonl=sys.stdout)
        if jsonl_file is not None:
            out = jsonl_file

            def to_file(entry: LogEntry) -> None:
                out.write(json.dumps(entry.to_json(), ensure_ascii=False) + "\n")
                out.flush()

            log.listeners.append(to_file)
    else:
        log = CommLog(text=sys.stdout, jsonl=jsonl_file)
    try:
        tap = Proxy(target, port, host or "127.0.0.1", log=log, pcap=pcap, log_rate=log_rate, net=net,
                    udp_idle=udp_idle)
    except (ValueError, OSError) as exc:
        if jsonl_file is not None:
            jsonl_file.close()
        if isinstance(exc, OSError) and pcap is not None:   # the target URL is only parsed (ValueError)
            raise click.BadParameter(f"cannot write {pcap}: {exc.strerror or exc}", param_hint="--pcap") from None
        raise click.BadParameter(str(exc), param_hint="--to") from None

    async def main() -> None:
        stop = asyncio.Event()
        loop = asyncio.get_running_loop()
        for sig in (signal.SIGINT, signal.SIGTERM):
            with contextlib.suppress(NotImplementedError, RuntimeError):
                loop.add_signal_handler(sig, stop.set)
        try:
            await tap.start()
        except OSError as exc:
            raise click.ClickException(f"cannot listen on {listen}: {exc.strerror or exc}") from None
        click.echo(f"proxy {tap.address} -> {target}", err=True)
        server = None
        if control_addr is not None:
            from ..testing.netcontrol import ControlServer

            try:
                server = ControlServer(net, loop, *control_addr).start()
            except ValueError as exc:
                await tap.close()
                raise click.BadParameter(str(exc), param_hint="--control") from None
            except OSError as exc:
                await tap.close()
                raise click.ClickException(f"cannot listen on --control {control}: {exc.strerror or exc}") from None
            click.echo(f"control {server.url}  (wsg world --sim {server.url} net ...)", err=True)
        for kind, params in net.state().items():
            click.echo(f"network fault: {kind} {params}", err=True)
        # What start-up made (imports, catalog) lives until exit: freezing it keeps the garbage
        # collector's full passes from scanning it (20-35 ms each, measured under a flood; < 1 ms frozen)
        gc.freeze()
        try:
            await stop.wait()
        finally:
            if server is not None:
                server.close()
            await tap.close()
            s = tap.stats
            click.echo(f"stopped: {s.connections} client(s), {s.frames['tx']} request(s), "
                       f"{s.frames['rx']} reply frame(s)"
                       + (f", {s.not_logged} not logged (over --log-rate)" if s.not_logged else ""), err=True)

    try:
        asyncio.run(main())
    finally:
        if jsonl_file is not None:
            jsonl_file.close()


def _address(text: str, hint: str) -> tuple[str, int]:
    """``[HOST:]PORT`` -> (host, port); host 127.0.0.1 unless given."""
    host, _, port_text = text.rpartition(":")
    try:
        port = int(port_text)
        if not 0 <= port <= 65535:
            raise ValueError
    except ValueError:
        raise click.BadParameter(f"{text!r}: give PORT or HOST:PORT", param_hint=hint) from None
    return host or "127.0.0.1", port


def start_fault(net: Any, spec: str) -> None:
    """``--net latency:ms=200,jitter=50`` switched on in ``net`` (a NetFaults); bad ones are usage errors."""
    from ..server.netfault import NetFaultError, parse_number

    kind, _, rest = spec.partition(":")
    params: dict[str, object] = {}
    for item in filter(None, rest.split(",")):
        key, eq, value = item.partition("=")
        if not eq:
            raise click.BadParameter(f"{spec!r}: parameters are KEY=VALUE, not {item!r}", param_hint="--net")
        key = key.strip()
        params[key] = value.strip() if key == "on" else parse_number(value.strip())
    try:
        net.set(kind.strip(), params)
    except NetFaultError as exc:
        raise click.BadParameter(f"{spec!r}: {exc}", param_hint="--net") from None
