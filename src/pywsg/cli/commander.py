"""``wsg commander``: the WSG Commander (000 §2) as a local web page, for real and virtual grippers."""

from __future__ import annotations

import asyncio
import contextlib
import webbrowser

import click

from . import signals
from .runner import PORT


@click.command("commander")
@click.option("--url", "gripper_url", default=None, metavar="URL",
              help="Gripper to connect to at once: tcp://HOST[:1000], udp://HOST[:1500], "
                   "serial:///dev/ttyUSB0?baudrate=115200, can://can0?interface=socketcan "
                   "(default: none, choose in Gripper → Connect; `wsg --url` only fills the dialog).")
@click.option("--host", default="127.0.0.1", show_default=True,
              help="Address the page is served on. Anything but loopback needs a password (generated and "
                   "printed when not given), as the web interface.")
@click.option("--port", type=PORT, default="8081", show_default=True, help="Port of the page (0: any free port).")
@click.option("--password", default=None, envvar="WSG_COMMANDER_PASSWORD",
              help="Login password for a non-loopback --host (or set WSG_COMMANDER_PASSWORD).")
@click.option("--timeout", type=click.FloatRange(min=0.01), default=3.0, show_default=True, metavar="SECONDS",
              help="Seconds to wait for each reply from the gripper.")
@click.option("--open/--no-open", "open_browser", default=False, show_default=True,
              help="Open the page in the default web browser.")
@click.pass_context
def commander(ctx: click.Context, gripper_url: str | None, host: str, port: int | None, password: str | None,
              timeout: float, open_browser: bool) -> None:
    """Serve the WSG Commander in the browser: Connect, predefined commands, the Custom Command
    Editor with live packet decoding, and the Communication Log (save as JSON lines or pcapng).

    Works with any gripper the driver reaches: a real WSG over TCP, UDP, RS232 or CAN, or `wsg sim`.
    Closing the page (or stopping this command) announces the disconnect (07h) over TCP, so the
    gripper does not FAST STOP. Ctrl-C stops it.

    \b
    Example:
      wsg sim &                                   # or a real gripper
      wsg commander --url tcp://127.0.0.1:1000    # then open http://127.0.0.1:8081/
    """
    from ..web.commander import serve_commander

    root = ctx.find_root().obj or {}
    suggest = gripper_url or root.get("url") or ""
    if port is None:
        raise click.UsageError("--port off: the Commander is a page, it needs a port")

    async def main() -> None:
        handle = await serve_commander(host, port, url=suggest, connect=gripper_url is not None,
                                       password=password, timeout=timeout)
        click.echo(f"WSG Commander on {handle.url} (Ctrl-C stops it)")
        if open_browser:
            with contextlib.suppress(Exception):
                webbrowser.open(handle.url)
        try:
            await asyncio.Event().wait()
        finally:
            await handle.close()

    try:
        signals.run(main())
    except OSError as exc:
        raise click.ClickException(f"cannot serve on {host}:{port}: {exc.strerror or exc}") from None
