"""``wsg decode``: decode WSG frames given as hex (the manual's communication log, by hand)."""

from __future__ import annotations

import json
import sys
from collections.abc import Callable, Collection, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol, TypeVar

import click

from ..protocol.decode import DecodedFrame, Direction, decode_bytes, parse_hex

if TYPE_CHECKING:
    from ..capture.reader import CapturedFrame, LoggedFrame


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
    if path is not None:  # file and capture input, read by pywsg.capture.reader
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


class _ToJson(Protocol):
    def to_json(self) -> dict[str, Any]: ...


_T = TypeVar("_T", bound=_ToJson)


def emit(frames: list[DecodedFrame], as_json: bool) -> None:
    """Print decoded frames as text or JSON (shared by file and capture input)."""
    _print_blocks(frames, as_json, lambda f: f.lines())


def _print_blocks(frames: Sequence[_T], as_json: bool, lines: Callable[[_T], list[str]]) -> None:
    """Print ``frames`` as one JSON list, or as text blocks of ``lines(frame)`` apart by a blank line."""
    if as_json:
        click.echo(json.dumps([f.to_json() for f in frames], indent=2, ensure_ascii=False))
        return
    for i, f in enumerate(frames):
        if i:
            click.echo()
        click.echo("\n".join(lines(f)))


def decode_file(path: str | Path, ports: Collection[int] = (), as_json: bool = False,
                direction: Direction | None = None) -> int:
    """Decode a capture, JSON-lines log, hex-dump or binary file and print it; returns the exit status
    (1 when any frame is bad, truncated or the file cannot be read)."""
    # imported here so that hex decoding never loads dpkt
    from ..capture.reader import bytes_from_file, frames_from_capture, frames_from_jsonl, is_capture, is_jsonl

    try:
        if is_jsonl(path):
            logged = frames_from_jsonl(path, direction)
            _print_framed(logged, as_json, "no WSG frames in the log")
            decoded = [f.decoded for f in logged]
        elif is_capture(path):
            captured = frames_from_capture(path, ports or None)
            if direction is not None:
                for c in captured:
                    if c.decoded.command_id is not None and not c.decoded.error:
                        c.decoded = decode_bytes(c.decoded.raw, direction)[0]
            _print_framed(captured, as_json, "no WSG frames in the capture")
            decoded = [c.decoded for c in captured]
        else:
            data = bytes_from_file(path)
            if not data:
                click.echo(f"error: {path}: no bytes", err=True)
                return 1
            decoded = decode_bytes(data, direction)
            emit(decoded, as_json)
    except BrokenPipeError:
        raise  # the reader went away (`| head`): click leaves quietly
    except (OSError, ValueError) as exc:
        click.echo(f"error: {path}: {exc}", err=True)
        return 1
    return 1 if any(d.error or d.checksum_ok is False for d in decoded) else 0


def _print_framed(frames: Sequence[LoggedFrame | CapturedFrame], as_json: bool, none: str) -> None:
    """Print frames with a header line each (time, direction), or as one JSON list."""
    _print_blocks(frames, as_json, lambda f: [f.header(), *f.decoded.lines()])
    if not frames:
        click.echo(none, err=True)


__all__ = ["Direction", "decode", "decode_file", "emit"]
