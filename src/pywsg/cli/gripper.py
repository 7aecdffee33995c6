"""Driver-backed subcommands: one per method of :class:`pywsg.AsyncGripper` (the manual's commands).

Every command takes ``--json``, ``--log``, ``--log-file`` and ``--timeout`` (see :mod:`.runner`);
widths are mm, speeds mm/s, accelerations mm/s², forces N, temperatures °C.
"""

from __future__ import annotations

from collections.abc import Awaitable, Callable
from typing import Any

import click

from . import signals
from .runner import NumberArgsCommand, Options, common_options, emit, fail, options

Action = Callable[[Any], Awaitable[Any]]

DEFAULT_SPEED = 50.0  # mm/s: a careful default, well inside every model's range
MOTION_TIMEOUT = 60.0  # s: the driver's default wait for a motion's final frame


def _driver() -> Any:
    import pywsg

    found = getattr(pywsg, "AsyncGripper", None)  # the public name (docs/architecture.md)
    if found is None:
        from ..client import AsyncGripper as found
    return found


async def _session(opts: Options, action: Action, motion_timeout: float) -> Any:
    g = _driver()(opts.url, timeout=opts.timeout, motion_timeout=motion_timeout,
                  connect_timeout=min(opts.timeout, 5.0))
    if opts.log is not None:
        g.on_frame = opts.log.hook
    await g.connect()
    try:
        return await action(g)
    finally:
        await g.close()


def run(ctx: click.Context, kw: dict[str, Any], action: Action, motion_timeout: float = MOTION_TIMEOUT) -> Any:
    """Open the gripper at ``--url``, run ``action(gripper)``, close; errors exit with their status."""
    opts = options(ctx, kw.pop("as_json"), kw.pop("log_flag"), kw.pop("log_file"), kw.pop("timeout"))
    ctx.meta["wsg_json"] = opts.as_json
    try:
        return signals.run(_session(opts, action, motion_timeout))
    except Exception as exc:  # WsgError, OSError, ValueError from the driver: all reported the same way
        fail(exc, opts.as_json, opts.url)


def as_json(ctx: click.Context) -> bool:
    return bool(ctx.meta.get("wsg_json"))


def _done(ctx: click.Context, what: str, result: dict[str, Any]) -> None:
    if as_json(ctx):
        emit({"ok": True, "command": what, **result}, True)
    else:
        details = ", ".join(f"{k} {v:.2f}" if isinstance(v, float) else f"{k} {v}" for k, v in result.items())
        click.echo(f"{what}: done" + (f" ({details})" if details else ""))


def _motion_options(f: Callable[..., Any]) -> Callable[..., Any]:
    f = click.option("--motion-timeout", type=click.FloatRange(min=0.01), default=MOTION_TIMEOUT, show_default=True,
                     metavar="SECONDS", help="How long to wait for the motion's final reply.")(f)
    f = click.option("--wait/--no-wait", default=True, show_default=True,
                     help="Wait for the motion's final reply (--no-wait: return after E_CMD_PENDING; UDP and "
                          "serial only, since over TCP the 07h sent on exit aborts the motion).")(f)
    return f


NO_WAIT_OVER_TCP = (
    "--no-wait over TCP would abort the motion at once: wsg ends its TCP session with the disconnect "
    "announcement (07h) as it exits, and the gripper aborts a motion running when 07h arrives (000 §3.1.2). "
    "Leave out --no-wait (wsg waits for the final reply), or send the command over UDP or serial, which "
    "have no disconnect announcement (--url udp://HOST:1500)")


def refuse_no_wait_over_tcp(ctx: click.Context, wait: bool) -> None:
    """``--no-wait`` over TCP: refused with the reason (exit 2), since the 07h sent on exit stops the motion."""
    if wait:
        return
    from ..client import parse_url

    root = ctx.find_root().obj or {}
    url = ctx.meta.get("pywsg.url") or root.get("url") or "tcp://127.0.0.1:1000"
    try:
        scheme = parse_url(url).scheme
    except ValueError:
        return  # the connection attempt reports the bad URL
    if scheme == "tcp":
        raise click.UsageError(NO_WAIT_OVER_TCP, ctx)


def _readback(g: Any) -> Awaitable[float]:
    return g.width()  # type: ignore[no-any-return]


SPEED = click.option("--speed", type=click.FloatRange(min=0, min_open=True), default=DEFAULT_SPEED,
                     show_default=True, metavar="MM/S",
                     help="Finger speed in mm/s, more than 0 (the gripper clamps it to its limits).")

#: Widths may be negative (``wsg move --relative -5``): such an argument is a number, not an option.
def warn(text: str) -> None:
    click.echo(f"warning: {text}", err=True)


def warn_outside(value: float, lo: float, hi: float, unit: str, limits: str, what: str, extra: str = "") -> None:
    """Warn (stderr, one line) when ``value`` is outside ``lo..hi``, naming the limit and where the
    gripper clamps it: it executes the command with the clamped value, so the result differs from what
    was asked (the web API refuses the same request with 422)."""
    tolerance = 1e-4 * max(1.0, abs(hi))   # limits arrive as float32 (53h, 000 §3.5.4)
    if lo - tolerance <= value <= hi + tolerance:
        return
    edge = hi if value > hi else lo
    warn(f"{value:g} {unit} is outside {limits} {lo:g}..{hi:g} {unit}: the gripper clamps {what} to {edge:g} {unit}"
         + extra)


async def _check_stroke(g: Any, lim: Any, width: float, relative: bool, what: str = "the target") -> None:
    """A width outside 0..stroke mm: 21h, 25h and 26h clamp it (000 §3.2.2, §3.2.6, §3.2.7)."""
    target = (await g.width()) + width if relative else width
    warn_outside(target, 0.0, lim.stroke, "mm", "the stroke", what)


def _check_speed(lim: Any, speed: float) -> None:
    """A speed outside the 53h speed limits (mm/s): the gripper clamps it."""
    warn_outside(speed, lim.min_speed, lim.max_speed, "mm/s", "the speed limits", "the speed")


async def _check_force(g: Any, lim: Any, force: float) -> None:
    """A force limit outside min_force..nominal_force N (..overdrive_force in overdrive mode, 000 §3.3.3,
    §3.3.8): the gripper clamps it."""
    from ..protocol import SystemFlag

    overdrive = bool(await g.system_state() & SystemFlag.SF_OVERDRIVE_MODE)
    hi = lim.overdrive_force if overdrive else lim.nominal_force
    extra = ""
    if not overdrive and lim.nominal_force < force and lim.overdrive_force > lim.nominal_force:
        extra = f" (`wsg overdrive on` allows up to {lim.overdrive_force:g} N)"
    warn_outside(force, lim.min_force, hi, "N", "the force limits" + (" in overdrive" if overdrive else ""),
                 "the force limit", extra)


async def _check_motion(g: Any, width: float | None, speed: float, *, relative: bool = False,
                        force: float | None = None, what: str = "the target") -> Any:
    """Warn about every value of a motion command the gripper will clamp (one 53h request); returns
    the limits read."""
    lim = await g.limits()
    if width is not None:
        await _check_stroke(g, lim, width, relative, what)
    _check_speed(lim, speed)
    if force is not None:
        await _check_force(g, lim, force)
    return lim


async def _check_acceleration(g: Any, acceleration: float) -> None:
    """An acceleration outside the 53h limits (mm/s²): 30h clamps it (000 §3.3.1)."""
    lim = await g.limits()
    warn_outside(acceleration, lim.min_acceleration, lim.max_acceleration, "mm/s²", "the acceleration limits",
                 "the acceleration")


async def _check_force_limit(g: Any, force: float) -> None:
    await _check_force(g, await g.limits(), force)


# -- motion ------------------------------------------------------------------------------------

@click.command()
@click.option("--direction", type=click.Choice(["default", "positive", "negative"]), default="default",
              show_default=True, help="Homing direction (default: the one set in the gripper's web interface).")
@_motion_options
@common_options
@click.pass_context
def home(ctx: click.Context, /, direction: str, wait: bool, motion_timeout: float, **kw: Any) -> None:
    """Reference the fingers (20h Homing) by moving to the mechanical end stop."""
    refuse_no_wait_over_tcp(ctx, wait)

    async def act(g: Any) -> dict[str, Any]:
        await g.home(direction, wait=wait)
        return {"width": await _readback(g)} if wait else {"pending": True}
    _done(ctx, "home", run(ctx, kw, act, motion_timeout))


@click.command(cls=NumberArgsCommand)
@click.argument("width", type=float)
@SPEED
@click.option("--relative", is_flag=True, help="WIDTH is a distance from the current width (mm, may be negative).")
@click.option("--stop-on-block", is_flag=True,
              help="Stop when blocked (E_AXIS_BLOCKED) instead of clamping with the force limit.")
@_motion_options
@common_options
@click.pass_context
def move(ctx: click.Context, /, width: float, speed: float, relative: bool, stop_on_block: bool, wait: bool,
         motion_timeout: float, **kw: Any) -> None:
    """Pre-position the fingers (21h) to WIDTH mm (or by WIDTH mm with --relative)."""
    refuse_no_wait_over_tcp(ctx, wait)

    async def act(g: Any) -> dict[str, Any]:
        await _check_motion(g, width, speed, relative=relative)
        await g.move(width, speed, relative=relative, stop_on_block=stop_on_block, wait=wait)
        return {"width": await _readback(g)} if wait else {"pending": True}
    _done(ctx, "move", run(ctx, kw, act, motion_timeout))


@click.command()
@click.argument("width", type=float)
@SPEED
@click.option("--force", type=click.FloatRange(min=0), default=None, metavar="N",
              help="Set the gripping force limit in N first (default: keep the current limit).")
@_motion_options
@common_options
@click.pass_context
def grip(ctx: click.Context, /, width: float, speed: float, force: float | None, wait: bool, motion_timeout: float,
         **kw: Any) -> None:
    """Grip a part of nominal width WIDTH mm (25h Grip Part). Exit 1 with E_CMD_FAILED when no part is found."""
    refuse_no_wait_over_tcp(ctx, wait)

    async def act(g: Any) -> dict[str, Any]:
        await _check_motion(g, width, speed, force=force, what="the part width")
        await g.grip(width, speed, force, wait=wait)
        if not wait:
            return {"pending": True}
        return {"width": await _readback(g), "force": await g.force(), "state": (await g.gripper_state()).name}
    _done(ctx, "grip", run(ctx, kw, act, motion_timeout))


@click.command()
@click.argument("width", type=float, required=False)
@SPEED
@_motion_options
@common_options
@click.pass_context
def release(ctx: click.Context, /, width: float | None, speed: float, wait: bool, motion_timeout: float,
            **kw: Any) -> None:
    """Release a gripped part by opening to WIDTH mm (26h Release Part; default: fully open, the stroke)."""
    refuse_no_wait_over_tcp(ctx, wait)

    async def act(g: Any) -> dict[str, Any]:
        lim = await _check_motion(g, width, speed)
        w = width if width is not None else lim.stroke
        await g.release(w, speed, wait=wait)
        return {"width": await _readback(g)} if wait else {"pending": True}
    _done(ctx, "release", run(ctx, kw, act, motion_timeout))


def _simple(name: str, method: str, doc: str) -> click.Command:
    @click.command(name, help=doc)
    @common_options
    @click.pass_context
    def cmd(ctx: click.Context, /, **kw: Any) -> None:
        async def act(g: Any) -> dict[str, Any]:
            await getattr(g, method)()
            return {}
        run(ctx, kw, act)
        _done(ctx, name, {})
    return cmd


stop = _simple("stop", "stop", "Stop any finger motion (22h); a running motion ends with E_CMD_ABORTED.")
fast_stop = _simple("fast-stop", "fast_stop",
                    "Issue a FAST STOP (23h): motion commands are refused (E_ACCESS_DENIED) until `wsg ack`.")
ack = _simple("ack", "acknowledge", 'Acknowledge a FAST STOP or fault (24h with the key "ack").')
tare = _simple("tare", "tare", "Zero the force sensor (38h; not while HOLDING a part: E_ACCESS_DENIED).")


# -- reading -----------------------------------------------------------------------------------

def _getter(name: str, method: str, doc: str, key: str) -> click.Command:
    @click.command(name, help=doc)
    @common_options
    @click.pass_context
    def cmd(ctx: click.Context, /, **kw: Any) -> None:
        async def act(g: Any) -> Any:
            return await getattr(g, method)()
        emit(run(ctx, kw, act), as_json(ctx), key)
    return cmd


info = _getter("info", "info", "Device type, hardware revision, firmware version, serial number (50h).", "info")
state = _getter("state", "state", "Width (mm), speed (mm/s), force (N), gripper state, system flags and "
                "temperature (°C), read in one go (43h, 44h, 45h, 41h, 40h, 46h).", "state")
limits = _getter("limits", "limits", "System limits (53h): stroke mm, speeds mm/s, accelerations mm/s², forces N.",
                 "limits")
temp = _getter("temp", "temperature", "Device temperature in °C (46h).", "temperature")
width_cmd = _getter("width", "width", "Opening width in mm (43h).", "width")
speed_cmd = _getter("speed", "speed", "Finger speed in mm/s (44h).", "speed")
force_cmd = _getter("force", "force", "Gripping force in N (45h).", "force")
flags_cmd = _getter("flags", "system_state", "System state flags (40h, manual Appendix B).", "flags")
gstate_cmd = _getter("gripper-state", "gripper_state", "Grasping state (41h): IDLE, GRIPPING, NO_PART, PART_LOST, "
                     "HOLDING, RELEASING, POSITIONING, ERROR.", "gripper_state")


@click.command()
@click.option("--reset", is_flag=True, help="Reset the counters after reading them.")
@common_options
@click.pass_context
def stats(ctx: click.Context, /, reset: bool, **kw: Any) -> None:
    """Gripping statistics (42h): total grips, grips with no part found, parts lost."""
    async def act(g: Any) -> Any:
        return await g.statistics(reset)
    emit(run(ctx, kw, act), as_json(ctx), "statistics")


def _get_set(name: str, getter: str, setter: str, key: str, unit: str, doc: str,
             check: Callable[[Any, float], Awaitable[None]]) -> click.Command:
    """A read/set command; ``check(gripper, value)`` warns before a value the gripper will clamp."""
    @click.command(name, help=f"{doc} Without VALUE: read it; with VALUE ({unit}): set it (session only).")
    @click.argument("value", type=float, required=False)
    @common_options
    @click.pass_context
    def cmd(ctx: click.Context, /, value: float | None, **kw: Any) -> None:
        async def act(g: Any) -> Any:
            if value is not None:
                await check(g, value)
                await getattr(g, setter)(value)
            return await getattr(g, getter)()  # read back: the gripper clamps to its limits
        emit({key: run(ctx, kw, act)}, as_json(ctx), key)
    return cmd


accel = _get_set("accel", "acceleration", "set_acceleration", "acceleration", "mm/s²",
                 "Acceleration for motions in mm/s² (30h/31h).", _check_acceleration)
force_limit = _get_set("force-limit", "force_limit", "set_force_limit", "force_limit", "N",
                       "Gripping force limit in N (32h/33h).", _check_force_limit)


@click.command("soft-limits")
@click.argument("minus", type=float, required=False)
@click.argument("plus", type=float, required=False)
@click.option("--clear", is_flag=True, help="Clear the soft limits (36h).")
@common_options
@click.pass_context
def soft_limits(ctx: click.Context, /, minus: float | None, plus: float | None, clear: bool, **kw: Any) -> None:
    """Soft limits in mm (34h/35h/36h): no argument reads them, MINUS PLUS sets them, --clear clears them."""
    if (minus is None) != (plus is None):
        raise click.UsageError("give both MINUS and PLUS (mm), or neither")

    async def act(g: Any) -> Any:
        if clear:
            await g.clear_soft_limits()
        elif minus is not None and plus is not None:
            await g.set_soft_limits(minus, plus)
        return await g.soft_limits()
    result = run(ctx, kw, act)
    emit(result if result is not None else {"minus": None, "plus": None}, as_json(ctx), "soft_limits")


@click.command()
@click.argument("mode", type=click.Choice(["on", "off"]))
@common_options
@click.pass_context
def overdrive(ctx: click.Context, /, mode: str, **kw: Any) -> None:
    """Force overdrive mode (37h): on lets the force limit go up to the overdrive force."""
    async def act(g: Any) -> dict[str, Any]:
        await g.overdrive(mode == "on")
        return {"overdrive": mode == "on"}
    _done(ctx, "overdrive", run(ctx, kw, act))


@click.command()
@click.argument("action", type=click.Choice(["get", "set"]), default="get")
@click.argument("text", required=False)
@common_options
@click.pass_context
def tag(ctx: click.Context, /, action: str, text: str | None, **kw: Any) -> None:
    """The device tag (51h/52h): `wsg tag` or `wsg tag get` reads it, `wsg tag set TEXT` sets it
    (at most 64 printable ASCII characters)."""
    if action == "set" and text is None:
        raise click.UsageError("wsg tag set TEXT")

    async def act(g: Any) -> Any:
        if action == "set":
            await g.set_tag(text)
        return await g.tag()
    emit({"tag": run(ctx, kw, act)}, as_json(ctx), "tag")


@click.command()
@click.argument("n", type=click.IntRange(1, 2), metavar="1|2")
@click.argument("what", type=click.Choice(["info", "flags", "power", "data"]))
@click.argument("mode", type=click.Choice(["on", "off"]), required=False)
@common_options
@click.pass_context
def finger(ctx: click.Context, /, n: int, what: str, mode: str | None, **kw: Any) -> None:
    """Finger 1 or 2 (60h..63h, 70h..73h): info (type, data size in bytes), flags, power on|off, data."""
    if what == "power" and mode is None:
        raise click.UsageError("wsg finger N power on|off")

    async def act(g: Any) -> Any:
        f = g.finger(n)
        if what == "power":
            await f.power(mode == "on")
            return {"power": mode}
        return await getattr(f, what)()
    result = run(ctx, kw, act)
    emit(result, as_json(ctx), what if what != "data" else "data")


@click.command("loop")
@click.argument("payload", nargs=-1)
@common_options
@click.pass_context
def loop_cmd(ctx: click.Context, /, payload: tuple[str, ...], **kw: Any) -> None:
    """Loop-back test (06h): the gripper returns PAYLOAD (editor syntax, as for `wsg send`; default "pywsg")."""
    from ..protocol.editor import PayloadSyntaxError, parse_payload

    try:
        data = parse_payload(payload) if payload else b"pywsg"
    except PayloadSyntaxError as exc:
        raise click.UsageError(str(exc)) from None

    async def act(g: Any) -> Any:
        return await g.loop(data)
    back = run(ctx, kw, act)
    emit({"sent": data, "returned": back, "equal": back == data}, as_json(ctx), "loop")


GRIPPER_COMMANDS: dict[str, click.Command] = {
    c.name or "": c for c in (
        home, move, grip, release, stop, fast_stop, ack, tare, info, state, limits, temp, width_cmd, speed_cmd,
        force_cmd, flags_cmd, gstate_cmd, stats, accel, force_limit, soft_limits, overdrive, tag, finger, loop_cmd,
    )
}
