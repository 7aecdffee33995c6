"""``wsg decode``: decode WSG frames given as hex (the manual's communication log, by hand)."""

from __future__ import annotations

import json
import sys

import click

from ..protocol.decode import DecodedFrame, Direction, decode_bytes, parse_hex


@click.command()
@click.argument("hexdata", nargs=-1)
@click.option("--json", "as_json", is_flag=True, help="Print a JSON list, one object per frame.")
@click.option(
    "--direction", type=click.Choice(["request", "reply"]), default=None,
    help="Treat every frame as a request (host to gripper) or reply; default: guess per frame.",
)
@click.option(
    "-f", "--file", "path", type=click.Path(exists=True, dir_okay=False),
    help="Decode a file instead: pcap/pcapng capture (TCP streams reassembled, UDP datagrams), "
    "JSON lines (wsg proxy --jsonl, wsg --log-file), hex dump (plain hex, xxd, hexdump -C) or raw "
    "binary frames.",
)
@click.option(
    "--port", "ports", type=int, multiple=True, metavar="PORT",
    help="Gripper-side port in a capture (repeatable; default 1000, 1500, 1501): sets the direction.",
)
def decode(hexdata: tuple[str, ...], as_json: bool, direction: str | None, path: str | None,
           ports: tuple[int, ...]) -> None:
    """Decode frames given as hex bytes.

    HEXDATA may hold several frames and any spacing: "AA AA AA 20 02 00 00 00 B3 FD",
    "AAh AAh AAh ...", "0xAA 0xAA ..." or "aaaaaa2002...". With no argument, hex is read
    from standard input. Prints per frame: direction guess, command name and ID, parameters
    with units, the status name for replies, and whether the checksum is right (with the
    expected value when not). Exit status 1 when any frame is bad or truncated.
    """
    if path is not None:  # file and capture input: pywsg.cli.capture (issue 5)
        from .capture import decode_file

        sys.exit(decode_file(path, ports, as_json, direction))  # type: ignore[arg-type]
    text = " ".join(hexdata) if hexdata else sys.stdin.read()
    try:
        data = parse_hex(text)
    except ValueError as exc:
        raise click.UsageError(str(exc)) from None
    if not data:
        raise click.UsageError("no bytes given")
    frames = decode_bytes(data, direction)  # type: ignore[arg-type]
    emit(frames, as_json)
    if any(f.error or f.checksum_ok is False for f in frames):
        sys.exit(1)


def emit(frames: list[DecodedFrame], as_json: bool) -> None:
    """Print decoded frames as text or JSON (shared by file and capture input)."""
    if as_json:
        click.echo(json.dumps([f.to_json() for f in frames], indent=2, ensure_ascii=False))
        return
    for i, f in enumerate(frames):
        if i:
            click.echo()
        click.echo("\n".join(f.lines()))


__all__ = ["Direction", "decode", "emit"]
