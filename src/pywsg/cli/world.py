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

from .runner import EXIT_CONNECTION

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
    block = f"{s['blocked_at']:g} mm" if s.get("blocked_at") is not None else "none"
    return [
        f"state        {s['gripper_state']}{'  (FAST STOP)' if s.get('fast_stop') else ''}",
        f"width        {s['width']:g} mm",
        f"force        {s['force']:g} N",
        f"temperature  {s['temperature']:g} °C",
        f"part         {part}",
        f"obstacle     {block}",
        f"faults       {', '.join(s.get('faults') or []) or 'none'}",
    ]


def _show(ctx: click.Context, reply: dict[str, Any]) -> None:
    if ctx.obj["world_json"]:
        click.echo(json.dumps(reply, ensure_ascii=False))
    elif "action" in reply:
        click.echo(f"{reply['action']}; gripper {reply['state']['gripper_state']} "
                   f"at {reply['state']['width']:g} mm")
    else:
        click.echo("\n".join(_state_lines(reply)))


@click.group("world")
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
      wsg world part 22            a 22 mm part between the fingers
      wsg world part --remove      take it away (while HOLDING: part lost)
      wsg world block 30           a rigid obstacle at 30 mm; `wsg world unblock`
      wsg world fault power on     supply fault: FAST STOP until `... power off` and an ACK
      wsg world fault finger on --finger 2
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
NUMBERS = {"ignore_unknown_options": True}


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
@click.argument("kind", type=click.Choice(["power", "current", "finger"]))
@click.argument("state", type=click.Choice(["on", "off"]))
@click.option("--finger", type=click.IntRange(1, 2), default=1, show_default=True, help="Finger for KIND finger.")
@click.pass_context
def fault(ctx: click.Context, kind: str, state: str, finger: int) -> None:
    """Switch a fault on or off: supply voltage (power), motor current (current), finger over-current."""
    body: dict[str, Any] = {"kind": kind, "on": state == "on"}
    if kind == "finger":
        body["finger"] = finger
    _run(ctx, "POST", "/fault", body)


@world.command("heat", context_settings=NUMBERS)
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
