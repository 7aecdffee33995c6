"""``wsg send``: the Custom Command Editor (command manual, chapter 2) on the command line."""

from __future__ import annotations

import json
import time
from typing import Any

import click
from click.shell_completion import CompletionItem

from ..capture.commlog import summary
from ..protocol import CATALOG, Frame, Status
from ..protocol.decode import decode_frame
from ..protocol.editor import PayloadSyntaxError, build_packet
from .runner import EXIT_CONNECTION, EXIT_STATUS, EXIT_USAGE, common_options, options


def _complete_id(_ctx: click.Context, _param: click.Parameter, incomplete: str) -> list[CompletionItem]:
    names = [(s.name.lower().replace("_", "-"), s.title) for s in CATALOG.values()]
    return [CompletionItem(n, help=t) for n, t in names if n.startswith(incomplete.lower())]


def _line(tag: str, frame_hex: str, text: str) -> str:
    return f"{tag}  {frame_hex}  {text}".rstrip()


@click.command(context_settings={"ignore_unknown_options": True})
@click.argument("command_id", metavar="ID", shell_complete=_complete_id)
@click.argument("payload", nargs=-1, metavar="[PAYLOAD]...")
@click.option("--dry-run", is_flag=True, help="Only assemble and show the packet; do not connect.")
@click.option("--follow", type=float, default=0.0, show_default=True, metavar="SECONDS",
              help="Keep printing received frames this long after the answer (auto-update packets).")
@common_options
@click.pass_context
def send(ctx: click.Context, /, command_id: str, payload: tuple[str, ...], dry_run: bool, follow: float,
         **kw: Any) -> None:
    """Send one command composed in the WSG Commander's Custom Command Editor syntax.

    ID is a number (33, 0x21, 21h) or a command name (preposition, get-system-state, ...).
    PAYLOAD items, separated by blanks or commas:

    \b
      32  0x20        one byte, decimal or hex (0..255; -128..-1 as signed)
      150.0f          float32, little endian (mm, mm/s, mm/s², N on the wire)
      '"ack"'         text in double quotes (quote it again for the shell)
      1000u16 -5i16   16/32-bit little-endian integers (u8 i8 u16 i16 u32 i32)

    Prints the packet bytes sent (CRC added) and every reply: for pending motion commands the
    E_CMD_PENDING acknowledge and, later, the final frame (waits up to --timeout seconds).

    \b
    Examples (the manual's):
      wsg send 1                       -> AA AA AA 01 00 00 E8 10
      wsg send 1 0x12 0x34             -> AA AA AA 01 02 00 12 34 6D 66
      wsg send set-acceleration 150.0f
      wsg send preposition 0 50.0f 100.0f
      wsg send 0x24 '"ack"'
      wsg send get-opening-width 1 100u16 --follow 2   (auto update every 100 ms)

    Exit status 1 when the (final) reply carries an error status; 3 when no reply came.
    """
    as_json, log_flag, log_file, timeout = kw.pop("as_json"), kw.pop("log_flag"), kw.pop("log_file"), kw.pop("timeout")
    try:
        packet = build_packet(command_id, payload)
    except PayloadSyntaxError as exc:
        if as_json:
            click.echo(json.dumps({"ok": False, "error": str(exc)}))
        click.echo(f"error: {exc}", err=True)
        ctx.exit(EXIT_USAGE)
    sent = decode_frame(Frame(packet.command_id, packet.payload), "request")
    result: dict[str, Any] = {"packet": sent.to_json(), "replies": [], "other": []}
    if not as_json:
        click.echo(_line("TX", sent.raw.hex(" ").upper(), f"{sent.command} ({packet.command_id:02X}h) {summary(sent)}"))
    if dry_run:
        if as_json:
            click.echo(json.dumps(result, ensure_ascii=False))
        return
    opts = options(ctx, as_json, log_flag, log_file, timeout)
    from .link import Link, LinkError

    final: Status | int | None = None
    try:
        with Link(opts.url, log=opts.log) as link:
            link.send_raw(packet.wire, Frame(packet.command_id, packet.payload))
            deadline = time.monotonic() + opts.timeout
            while final is None:
                frame = link.next_frame(deadline - time.monotonic())
                if frame is None:
                    break
                _show(frame, packet.command_id, result, as_json)
                if frame.command_id == packet.command_id and len(frame.payload) >= 2:
                    if frame.status != Status.E_CMD_PENDING:
                        final = frame.status
                    elif deadline - time.monotonic() < opts.timeout:  # pending: the final frame may take long
                        deadline = time.monotonic() + opts.timeout
            end = time.monotonic() + follow
            while follow > 0 and (left := end - time.monotonic()) > 0:
                frame = link.next_frame(left)
                if frame is not None:
                    _show(frame, packet.command_id, result, as_json)
    except (LinkError, OSError) as exc:
        if as_json:
            click.echo(json.dumps({**result, "ok": False, "error": str(exc)}, ensure_ascii=False))
        click.echo(f"error: {exc}", err=True)
        ctx.exit(EXIT_CONNECTION)
    if final is None:
        msg = f"no reply to {sent.command} ({packet.command_id:02X}h) within {opts.timeout:g} s"
        if as_json:
            click.echo(json.dumps({**result, "ok": False, "status": "E_TIMEOUT", "error": msg}, ensure_ascii=False))
        click.echo(f"error: E_TIMEOUT ({int(Status.E_TIMEOUT)}): {msg}", err=True)
        ctx.exit(EXIT_CONNECTION)
    code = int(final)
    ok = code == Status.E_SUCCESS
    if as_json:
        result.update(ok=ok, status=Status(code).name if code in Status._value2member_map_ else code)
        click.echo(json.dumps(result, ensure_ascii=False))
    if not ok:
        click.echo(f"error: {sent.command} ({packet.command_id:02X}h): {Status.describe(code)}", err=True)
        ctx.exit(EXIT_STATUS)


def _show(frame: Frame, sent_id: int, result: dict[str, Any], as_json: bool) -> None:
    d = decode_frame(frame, "reply")
    result["replies" if frame.command_id == sent_id else "other"].append(d.to_json())
    if not as_json:
        click.echo(_line("RX", d.raw.hex(" ").upper(), f"{d.command} ({frame.command_id:02X}h) {summary(d)}"))
