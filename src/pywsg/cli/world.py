"""``wsg world``: change the world of a running ``wsg sim`` (parts, obstacles, faults, heat).

Talks to the sim's HTTP control API on its web port (:mod:`pywsg.web.world_api`): no login on a
loopback-bound sim; elsewhere the web password (``--password`` or ``WSG_WEB_PASSWORD``).
"""

from __future__ import annotations

import json
import urllib.error
import urllib.request
from typing import Any

import click

from .main import SuggestingGroup
from .runner import EXIT_CONNECTION, NumberArgsCommand

DEFAULT_SIM = "http://127.0.0.1:8080"


class Unreachable(click.ClickException):
    """The sim's web port cannot be reached: exit 3, like every connection failure of `wsg`."""

    exit_code = EXIT_CONNECTION


def sim_base(sim: str) -> str:
    """The sim's web address as an http(s) URL: ``HOST[:PORT]`` means ``http://HOST[:PORT]``.

    Raises click.BadParameter (exit 2) for another scheme, e.g. the gripper's ``tcp://`` URL.
    """
    text = sim.strip().rstrip("/")
    if "://" not in text:
        text = f"http://{text}"
    scheme = text.split("://", 1)[0].lower()
    if scheme not in ("http", "https") or not text.split("://", 1)[1]:
        raise click.BadParameter(f"{sim!r}: expected the sim's web address, http://HOST:PORT "
                                 f"(wsg sim --web-port), e.g. {DEFAULT_SIM}", param_hint="--sim")
    return text


def call(sim: str, method: str, path: str, body: dict[str, Any] | None = None, password: str | None = None,
         timeout: float = 5.0) -> dict[str, Any]:
    """One request to the world API (``timeout`` in s); returns the JSON reply or raises a
    click.ClickException: exit 1 for a refusal, 2 for a bad ``sim`` URL, 3 when the sim is unreachable."""
    url = sim_base(sim) + "/api/world" + path
    data = json.dumps(body).encode() if body is not None else None
    req = urllib.request.Request(url, data=data, method=method)
    if data is not None:
        req.add_header("Content-Type", "application/json")
    if password:
        req.add_header("Authorization", f"Bearer {password}")
    try:
        with urllib.request.urlopen(req, timeout=timeout) as resp:
            reply: dict[str, Any] = json.loads(resp.read() or b"{}")
            return reply
    except urllib.error.HTTPError as exc:
        try:
            detail = json.loads(exc.read()).get("detail", exc.reason)
        except ValueError:
            detail = exc.reason
        hint = " (give --password or set WSG_WEB_PASSWORD)" if exc.code == 401 else ""
        if exc.code == 404:
            detail = f"{url}: not found — is this a wsg sim web port of this pywsg version?"
        raise click.ClickException(f"{detail}{hint}") from None
    except (urllib.error.URLError, OSError, ValueError) as exc:
        reason = getattr(exc, "reason", exc)
        raise Unreachable(
            f"cannot reach the sim at {sim}: {reason} (is `wsg sim` running with its web port on?)"
        ) from None


def _state_lines(s: dict[str, Any]) -> list[str]:
    part = f"{s['part']:g} mm" if s.get("part") is not None else "none"
    if s.get("part_inside") is not None:
        part += " (inside: a ring)" if s["part_inside"] else " (outside)"
    block = f"{s['blocked_at']:g} mm" if s.get("blocked_at") is not None else "none"
    return [
        f"state        {s['gripper_state']}{'  (FAST STOP)' if s.get('fast_stop') else ''}",
        f"width        {s['width']:g} mm",
        f"force        {s['force']:g} N",
        f"temperature  {s['temperature']:g} °C",
        f"part         {part}",
        f"obstacle     {block}",
        f"faults       {', '.join(s.get('faults') or []) or 'none'}",
        f"network      {_net_text(s.get('net') or {})}",
    ]


def _net_text(net: dict[str, Any]) -> str:
    """``{"latency": {"ms": 200, "jitter": 0}}`` -> ``latency ms=200 jitter=0``."""
    parts = [" ".join([kind, *(f"{k}={v:g}" for k, v in params.items())]) for kind, params in net.items()]
    return ", ".join(parts) or "healthy"


def _show(ctx: click.Context, reply: dict[str, Any]) -> None:
    if ctx.obj["world_json"]:
        click.echo(json.dumps(reply, ensure_ascii=False))
    elif "action" in reply and "gripper_state" not in reply.get("state", {}):
        click.echo(reply["action"])  # a wsg proxy --control: network faults only
    elif "action" in reply:
        click.echo(f"{reply['action']}; gripper {reply['state']['gripper_state']} "
                   f"at {reply['state']['width']:g} mm")
    elif "gripper_state" not in reply:
        click.echo(f"network      {_net_text(reply.get('net') or {})}")
    else:
        click.echo("\n".join(_state_lines(reply)))


@click.group("world", cls=SuggestingGroup)
@click.option("--sim", envvar="WSG_SIM", default=DEFAULT_SIM, show_default=True, metavar="URL",
              help="The sim's web address (wsg sim --web-port), or set WSG_SIM.")
@click.option("--password", envvar="WSG_WEB_PASSWORD", default=None,
              help="Web password of a sim not bound to loopback (or set WSG_WEB_PASSWORD).")
@click.option("--json", "as_json", is_flag=True, help="Print the API's JSON reply.")
@click.pass_context
def world(ctx: click.Context, sim: str, password: str | None, as_json: bool) -> None:
    """Change the world of a running `wsg sim`: parts, obstacles, faults, heat.

    \b
    Examples:
      wsg world part 22            a 22 mm part between the fingers (gripped from outside)
      wsg world part 40 --inside   a 40 mm ring around the fingers (gripped from inside)
      wsg world part --remove      take it away (while HOLDING: part lost)
      wsg world block 30           a rigid obstacle at 30 mm; `wsg world unblock`
      wsg world fault power on     supply fault: FAST STOP until `... power off` and an ACK
      wsg world fault finger on --finger 2
      wsg world fault ack on       acknowledge refused: 24h answers E_ACCESS_DENIED
      wsg world fault watchdog on --timeout 5   FAST STOP after 5 s without a request
      wsg world fault unplugged on --finger 1   a sensor finger stops talking
      wsg world slip --duration 2  the held part slides out: PART LOST in 2 s
      wsg world disconnect         the gripper closes its TCP connections
      wsg world net latency --ms 200 --jitter 50   network faults (wsg world net --help)
      wsg world net clear          every network fault off
      wsg world heat 40            40 °C warmer at once
      wsg world state              what the sim is doing now

    Exit status: 0 done, 1 the sim refused (bad value, password), 2 usage error, 3 sim unreachable.
    """
    parent = ctx.obj if isinstance(ctx.obj, dict) else {}
    ctx.obj = {**parent, "sim": sim, "password": password,
               "world_json": as_json or bool(parent.get("json"))}


def _set_json(ctx: click.Context, _param: click.Parameter, value: bool) -> None:
    if value:
        ctx.obj["world_json"] = True


#: ``--json`` after the subcommand too (``wsg world state --json``): the same as before it.
json_option = click.option("--json", "as_json", is_flag=True, expose_value=False,
                           callback=_set_json, help="Print the API's JSON reply.")

#: A negative DELTA (``wsg world heat -10``) is a number, not an option.
def _run(ctx: click.Context, method: str, path: str, body: dict[str, Any] | None = None) -> None:
    _show(ctx, call(ctx.obj["sim"], method, path, body, ctx.obj["password"]))


@world.command("part")
@json_option
@click.argument("width", type=float, required=False)
@click.option("--stiffness", type=float, default=None,
              help="Part stiffness in N/mm (default: rigid, a held part reads its own width).")
@click.option("--inside/--outside", default=False, show_default=True,
              help="Grip it from inside (a ring around the fingers, they open onto it) or from outside "
                   "(between the fingers, they close onto it; the default).")
@click.option("--remove", is_flag=True, help="Take the part away.")
@click.pass_context
def part(ctx: click.Context, width: float | None, stiffness: float | None, inside: bool, remove: bool) -> None:
    """Put a part of WIDTH mm between the fingers (--inside: a ring around them), or --remove it."""
    if remove:
        if width is not None:
            raise click.UsageError("give WIDTH or --remove, not both")
        _run(ctx, "DELETE", "/part")
        return
    if width is None:
        raise click.UsageError("give the part's WIDTH in mm (or --remove)")
    body: dict[str, Any] = {"width": width, "inside": inside}
    if stiffness is not None:
        body["stiffness"] = stiffness
    _run(ctx, "POST", "/part", body)


@world.command("block")
@json_option
@click.argument("width", type=float)
@click.pass_context
def block(ctx: click.Context, width: float) -> None:
    """Put a rigid obstacle in the fingers' way at WIDTH mm."""
    _run(ctx, "POST", "/block", {"width": width})


@world.command("unblock")
@json_option
@click.pass_context
def unblock(ctx: click.Context) -> None:
    """Remove the obstacle."""
    _run(ctx, "DELETE", "/block")


@world.command("fault")
@json_option
@click.argument("kind", type=click.Choice(["power", "current", "finger", "ack", "watchdog", "unplugged"]))
@click.argument("state", type=click.Choice(["on", "off"]))
@click.option("--finger", type=click.IntRange(1, 2), default=1, show_default=True,
              help="Finger for KIND finger and unplugged.")
@click.option("--timeout", type=click.FloatRange(min=0), default=1.0, show_default=True, metavar="S",
              help="KIND watchdog: FAST STOP after S seconds without a request.")
@click.pass_context
def fault(ctx: click.Context, kind: str, state: str, finger: int, timeout: float) -> None:
    """Switch a fault on or off: supply voltage (power), motor current (current), finger over-current
    (finger), acknowledge refused (ack), FAST STOP after a silent client (watchdog), a finger unplugged
    (unplugged). What each one reports: docs/testing.md, "World faults"."""
    body: dict[str, Any] = {"kind": kind, "on": state == "on"}
    if kind in ("finger", "unplugged"):
        body["finger"] = finger
    if kind == "watchdog":
        body["timeout"] = timeout
    _run(ctx, "POST", "/fault", body)


@world.command("slip")
@json_option
@click.option("--duration", type=click.FloatRange(min=0), default=1.0, show_default=True, metavar="S",
              help="Seconds (gripper clock) until the part is gone.")
@click.pass_context
def slip(ctx: click.Context, duration: float) -> None:
    """The part slides out of the fingers: a held part is lost (PART LOST) --duration s from now."""
    _run(ctx, "POST", "/slip", {"duration": duration})


@world.command("disconnect")
@json_option
@click.pass_context
def disconnect(ctx: click.Context) -> None:
    """The gripper closes its TCP connections: the sessions end without 07h, so FAST STOP (000 §1.4.2)."""
    _run(ctx, "POST", "/disconnect")


NET_KINDS = ("latency", "bandwidth", "slicer", "reset", "silent", "drop", "reorder", "garble", "clear")


@world.command("net")
@json_option
@click.argument("kind", type=click.Choice(NET_KINDS))
@click.argument("state", type=click.Choice(["on", "off"]), default="on")
@click.option("--ms", type=float, default=None, help="latency: delay of each reply, ms.")
@click.option("--jitter", type=float, default=None, help="latency: ± this many ms at random.")
@click.option("--rate", type=float, default=None, help="bandwidth: bytes per second.")
@click.option("--size", type=int, default=None, help="slicer: bytes per segment.")
@click.option("--gap", type=float, default=None, help="slicer: ms between segments.")
@click.option("--timeout", type=float, default=None,
              help="reset: seconds after a connection opens (0: at once); silent: close after this many s (0: never).")
@click.option("-p", "--p", "p", type=float, default=None, help="drop, reorder, garble: probability 0..1.")
@click.option("--seed", type=int, default=None, help="Restart the random sequence (repeatable runs).")
@click.pass_context
def net(ctx: click.Context, /, kind: str, state: str, **params: Any) -> None:
    """Switch a network fault of the sim's interfaces on (default) or off, at once.

    \b
    latency   --ms 200 --jitter 50    each reply later (TCP keeps the order)
    bandwidth --rate 500              replies trickle at 500 bytes/s
    slicer    --size 1 --gap 5        replies cut into 1-byte segments 5 ms apart
    reset     --timeout 0             TCP connections reset (RST) now and on connect
    silent    [--timeout 10]          no replies, requests ignored, connection open
    drop      -p 0.3                  UDP datagrams lost (both directions)
    reorder   -p 0.5                  UDP reply datagrams overtaken by the next one
    garble    -p 0.01                 bytes flipped (serial line noise; TCP and UDP too)
    clear                             every network fault off
    """
    if kind == "clear":
        _run(ctx, "DELETE", "/net")
        return
    body: dict[str, Any] = {"kind": kind, "on": state == "on"}
    body.update({k: v for k, v in params.items() if v is not None})
    _run(ctx, "POST", "/net", body)


@world.command("heat", cls=NumberArgsCommand)
@json_option
@click.argument("delta", type=float)
@click.pass_context
def heat(ctx: click.Context, delta: float) -> None:
    """Change the temperature by DELTA °C at once (it then relaxes to equilibrium)."""
    _run(ctx, "POST", "/heat", {"delta_c": delta})


@world.command("state")
@json_option
@click.pass_context
def state(ctx: click.Context) -> None:
    """Gripper state, width, force, temperature, part, obstacle and faults."""
    _run(ctx, "GET", "")


__all__ = ["call", "world"]
