"""``wsg log``: the Communication Log panel of the WSG Commander.

Two uses:

* ``wsg log FILE [--follow]`` prints a log written by ``--log-file FILE`` of any other command
  (JSON lines), re-decoded with the current catalog; ``--follow`` keeps reading like ``tail -f``,
  so one terminal can watch what scripts in another do.
* ``wsg log`` (no FILE) opens a session of its own on ``--url``: it sends the command lines read
  from standard input (Custom Command Editor syntax, one ``ID PAYLOAD...`` per line), optionally
  subscribes to auto-update streams, and logs every frame in and out until EOF, ``--duration``
  or Ctrl-C.
"""

from __future__ import annotations

import json
import os
import selectors
import sys
import time
from pathlib import Path
from typing import Any, TextIO

import click

from ..capture.commlog import CommLog, entry_from_json
from ..protocol import Command, Frame
from ..protocol.editor import PayloadSyntaxError, build_packet
from .runner import EXIT_CONNECTION, EXIT_USAGE, common_options, options

STREAMS = {"state": Command.GET_SYSTEM_STATE, "gripper-state": Command.GET_GRIPPER_STATE,
           "width": Command.GET_OPENING_WIDTH, "speed": Command.GET_SPEED, "force": Command.GET_FORCE}


def _print_file_line(line: str, as_json: bool, out: TextIO) -> None:
    line = line.strip()
    if not line:
        return
    try:
        obj = json.loads(line)
    except json.JSONDecodeError:
        out.write(f"(not a log line: {line[:60]!r})\n")
        return
    if as_json:
        out.write(json.dumps(obj, ensure_ascii=False) + "\n")
    elif "hex" in obj:
        out.write(entry_from_json(obj).line() + "\n")
    else:
        out.write(f"{obj.get('time', '')} {str(obj.get('direction', '')).upper()} -- {obj.get('error', '')}\n")
    out.flush()


def _show_file(path: Path, follow: bool, as_json: bool, duration: float | None) -> None:
    end = None if duration is None else time.monotonic() + duration
    with path.open("r", encoding="utf-8") as f:
        while True:
            line = f.readline()
            if line:
                _print_file_line(line, as_json, sys.stdout)
                continue
            if not follow or (end is not None and time.monotonic() >= end):
                return
            time.sleep(0.05)


@click.command("log")
@click.argument("file", type=click.Path(dir_okay=False, path_type=Path), required=False)
@click.option("--follow", is_flag=True, help="With FILE: keep reading as the file grows (like tail -f).")
@click.option("--subscribe", "streams", type=click.Choice(sorted(STREAMS)), multiple=True,
              help="Without FILE: start this auto-update stream (repeatable).")
@click.option("--period", type=click.IntRange(10, 65535), default=100, show_default=True, metavar="MS",
              help="Auto-update period in ms (the gripper's minimum is 10 ms).")
@click.option("--duration", type=click.FloatRange(min=0), default=None, metavar="SECONDS",
              help="Stop after this many seconds (default: until EOF on stdin / Ctrl-C; with --follow: forever).")
@common_options
@click.pass_context
def log_cmd(ctx: click.Context, /, file: Path | None, follow: bool, streams: tuple[str, ...], period: int,
            duration: float | None, **kw: Any) -> None:
    """Follow the communication log: each frame with time, direction (TX to the gripper, RX from it),
    hex bytes, and the decoded command, parameters (with units) and status.

    \b
    wsg log session.jsonl           print a log written with --log-file
    wsg log --follow session.jsonl  ... and keep following it
    wsg log --subscribe width       own session: log auto-updates; stdin lines are sent:
      echo 'get-system-state 0 0 0' | wsg log --duration 1
    """
    as_json = kw["as_json"]
    if file is not None:
        if not file.exists():
            if not follow:
                raise click.BadParameter(f"{file} does not exist", param_hint="FILE")
            file.touch()
        try:
            _show_file(file, follow, as_json, duration)
        except KeyboardInterrupt:
            pass
        return
    kw["log_flag"] = not as_json
    opts = options(ctx, kw.pop("as_json"), kw.pop("log_flag"), kw.pop("log_file"), kw.pop("timeout"))
    if as_json:  # JSON lines on stdout instead of text on stderr
        opts.log = CommLog(jsonl=sys.stdout, text=None) if opts.log is None else opts.log
        opts.log.jsonl = opts.log.jsonl or sys.stdout
    else:
        assert opts.log is not None
        opts.log.text = sys.stdout
    from .link import Link, LinkError

    end = None if duration is None else time.monotonic() + duration
    try:
        with Link(opts.url, log=opts.log) as link:
            for name in streams:
                link.send_frame(Frame(STREAMS[name], bytes([1]) + period.to_bytes(2, "little")))
            _session(link, end)
            for name in streams:  # stop the streams before leaving
                link.send_frame(Frame(STREAMS[name], bytes([0]) + period.to_bytes(2, "little")))
    except (LinkError, OSError) as exc:
        click.echo(f"error: {exc}", err=True)
        ctx.exit(EXIT_CONNECTION)
    except PayloadSyntaxError as exc:
        click.echo(f"error: {exc}", err=True)
        ctx.exit(EXIT_USAGE)
    except KeyboardInterrupt:
        pass


def _session(link: Any, end: float | None) -> None:
    """Send stdin lines, log everything received, until EOF (+ a grace period) or ``end``."""
    sel = selectors.DefaultSelector()
    eof_at: float | None = None
    pending = b""
    try:
        sel.register(0, selectors.EVENT_READ)
    except (ValueError, OSError):  # a regular file or /dev/null cannot be polled: read it whole
        for line in sys.stdin:
            _send_line(link, line)
        eof_at = time.monotonic()
    while True:
        now = time.monotonic()
        if end is not None and now >= end:
            return
        if eof_at is not None and end is None and now - eof_at > 1.0:
            return  # input done: give the last replies a second, then leave
        ev = link.next_event(0.02)
        while ev is not None:
            ev = link.next_event(0)
        if eof_at is None and sel.select(0):
            chunk = os.read(0, 4096)
            if not chunk:
                sel.unregister(0)
                eof_at = time.monotonic()
                chunk = b"\n"
            pending += chunk
            *lines, pending = pending.split(b"\n")
            for line in lines:
                _send_line(link, line.decode("utf-8", "replace"))


def _send_line(link: Any, line: str) -> None:
    line = line.split("#", 1)[0].strip()
    if not line:
        return
    head, _, rest = line.partition(" ")
    packet = build_packet(head, rest)
    link.send_raw(packet.wire, Frame(packet.command_id, packet.payload))
