"""Shared plumbing of the commander subcommands: common options, output, errors, the driver.

Exit status: 0 success; 1 the gripper answered an error status (name and meaning on stderr);
2 usage error (bad option, bad payload syntax); 3 no usable answer (connection refused or lost,
timeout, corrupted reply).
"""

from __future__ import annotations

import dataclasses
import difflib
import enum
import json
import sys
from collections.abc import Callable, Iterable, Mapping
from pathlib import Path
from typing import Any, NoReturn, TypeVar

import click

from ..capture.commlog import CommLog
from ..errors import HINT_ACKNOWLEDGE, HINT_ACKNOWLEDGE_AFTER, HINT_HOME
from ..protocol import Status, StatusError

F = TypeVar("F", bound=Callable[..., Any])

EXIT_STATUS = 1
EXIT_USAGE = 2
EXIT_CONNECTION = 3

UNITS: dict[str, str] = {
    "width": "mm", "speed": "mm/s", "force": "N", "temperature": "°C", "acceleration": "mm/s²",
    "stroke": "mm", "min_speed": "mm/s", "max_speed": "mm/s", "min_acceleration": "mm/s²",
    "max_acceleration": "mm/s²", "min_force": "N", "nominal_force": "N", "overdrive_force": "N",
    "force_limit": "N", "minus": "mm", "plus": "mm", "data_size": "bytes",
}


# -- values ------------------------------------------------------------------------------------

def jsonable(value: Any) -> Any:
    """Plain JSON types: flags -> list of names, enums -> name, dataclasses -> dicts, bytes -> hex."""
    if isinstance(value, enum.IntFlag):
        return [m.name for m in type(value) if m.value and m.name and value & m and m.value & (m.value - 1) == 0]
    if isinstance(value, enum.Enum):
        return value.name
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        out = {f.name: jsonable(getattr(value, f.name)) for f in dataclasses.fields(value)}
        for name in ("firmware_version",):  # computed properties worth showing
            if hasattr(value, name):
                out[name] = getattr(value, name)
        return out
    if isinstance(value, Mapping):
        return {str(k): jsonable(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [jsonable(v) for v in value]
    if isinstance(value, bytes):
        return value.hex(" ").upper()
    if isinstance(value, float):
        return round(value, 4)
    return value


def human(key: str, value: Any) -> str:
    """``value`` with its unit for people."""
    if isinstance(value, enum.IntFlag):
        names = jsonable(value)
        return ", ".join(names) if names else "(none)"
    if isinstance(value, enum.Enum):
        return f"{value.name} ({value.value})"
    if isinstance(value, float):
        unit = UNITS.get(key, "")
        return f"{value:.2f} {unit}".rstrip()
    if isinstance(value, bytes):
        return value.hex(" ").upper() or "(empty)"
    if value is None:
        return "(not set)"
    unit = UNITS.get(key, "")
    return f"{value} {unit}".rstrip() if isinstance(value, int) and unit else str(value)


def rows_of(value: Any) -> list[tuple[str, str]]:
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        rows = [(f.name, human(f.name, getattr(value, f.name))) for f in dataclasses.fields(value)]
        if hasattr(value, "firmware_version"):
            rows.append(("firmware_version", str(value.firmware_version)))
        return rows
    if isinstance(value, Mapping):
        return [(str(k), human(str(k), v)) for k, v in value.items()]
    return []


def emit(value: Any, as_json: bool, key: str = "value") -> None:
    """Print a result: a table of name/value rows, one value, or JSON."""
    if as_json:
        data = jsonable(value)
        if not isinstance(data, dict):
            data = {key: data}
        click.echo(json.dumps(data, ensure_ascii=False))
        return
    rows = rows_of(value)
    if rows:
        width = max(len(k) for k, _ in rows)
        for k, v in rows:
            click.echo(f"{k:<{width}}  {v}")
    else:
        click.echo(human(key, value))


# -- errors ------------------------------------------------------------------------------------

#: The driver's hints name Python calls; on the command line the same advice names `wsg` commands.
CLI_HINTS: dict[str, str] = {
    HINT_ACKNOWLEDGE: "run `wsg ack` first",
    HINT_ACKNOWLEDGE_AFTER: "then run `wsg ack`",
    HINT_HOME: "run `wsg home` first",
}

HELD_BY_ANOTHER = ("another client holds this gripper's TCP command interface (one client at a time; see "
                   "docs/sim.md): close that program (or its `wsg monitor`), or use the UDP interface")


def count(n: int, one: str, many: str | None = None) -> str:
    """``1 cycle``, ``3 cycles``: a number and its noun as English (``many``: an irregular plural)."""
    return f"{n} {one if n == 1 else (many or one + 's')}"


def cli_hint(text: str) -> str:
    """``text`` with the driver's Python hints replaced by the `wsg` commands that do the same."""
    for python, cli in CLI_HINTS.items():
        text = text.replace(python, cli)
    return text


def _label(command_id: int | None) -> str:
    from ..protocol import CATALOG

    if command_id is None:
        return ""
    spec = CATALOG.get(command_id)
    return spec.label if spec else f"command {command_id:02X}h"


def describe(exc: BaseException, url: str = "") -> tuple[int, str, dict[str, Any]]:
    """Exit code, one-line message and JSON fields for ``exc`` as the CLI reports it.

    Device answers read ``NAME (code): meaning``; failures found on this side (no reply in time, the
    connection dropped or was refused, a corrupted reply) say what happened, not a status code.
    """
    info: dict[str, Any] = {"ok": False}
    if isinstance(exc, StatusError):
        status = exc.status
        name = status.name if isinstance(status, Status) else f"UNKNOWN_STATUS_{int(status)}"
        from_device = getattr(exc, "from_device", True)
        label = _label(exc.command_id)
        prefix = f"{label}: " if label else ""
        if not from_device:
            detail = exc.detail or str(exc)
            if status == Status.E_TIMEOUT:
                kind = "timeout"
                detail += " (local timeout)" if "local" not in detail else ""
            elif status == Status.E_IO_ERROR:
                kind = "connection"
            else:
                kind = "protocol"
            message = prefix + detail
            info.update(error=message, local=kind, command_id=exc.command_id)
            return EXIT_CONNECTION, message, info
        meaning = status.description if isinstance(status, Status) else "unknown status code"
        flags = getattr(exc, "flags", None)
        message = cli_hint(str(exc))
        if name not in message:
            message = f"{name} ({int(status)}): {meaning} - {message}"
        if (status == Status.E_ACCESS_DENIED and flags is None and url.startswith("tcp:")
                and "FAST STOP" not in message):
            # a refused session cannot even read the system flags: every command gets E_ACCESS_DENIED
            message += f" - {HELD_BY_ANOTHER}"
        info.update(error=message, status=name, status_code=int(status), meaning=meaning, from_device=True,
                    command_id=exc.command_id)
        if flags is not None:
            info["flags"] = jsonable(flags)
        return EXIT_STATUS, message, info
    message = str(exc) or type(exc).__name__
    info["error"] = message
    if isinstance(exc, ValueError | TypeError):  # the driver refused an argument before sending
        return EXIT_USAGE, message, info
    if isinstance(exc, OSError):
        info["local"] = "connection"
    return EXIT_CONNECTION, message, info


def fail(exc: BaseException, as_json: bool = False, url: str = "") -> NoReturn:
    """Report ``exc`` on stderr (JSON on stdout too with --json) and exit with its status."""
    code, message, info = describe(exc, url)
    if as_json:
        click.echo(json.dumps(info, ensure_ascii=False))
    click.echo(f"error: {message}", err=True)
    sys.exit(code)


# -- typos -------------------------------------------------------------------------------------

def close_matches(word: str, choices: Iterable[str]) -> list[str]:
    """The choices that ``word`` is probably a typo of (difflib), best first."""
    return difflib.get_close_matches(word, list(choices), n=3, cutoff=0.6)


class NumberArgsCommand(click.Command):
    """A command whose arguments may be negative numbers (``wsg move -5 --relative``).

    click's ``ignore_unknown_options`` lets ``-5`` through as an argument, but it would let a
    mistyped ``--sped 50`` through too ("unexpected extra arguments"): here a word that starts with
    ``-``, is no number and names no option is refused as click refuses one, with a suggestion.
    """

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        settings = dict(kwargs.pop("context_settings", None) or {})
        settings["ignore_unknown_options"] = True
        kwargs["context_settings"] = settings
        super().__init__(*args, **kwargs)

    def parse_args(self, ctx: click.Context, args: list[str]) -> list[str]:
        known = {name for p in self.get_params(ctx) if isinstance(p, click.Option)
                 for name in (*p.opts, *p.secondary_opts)}
        for word in args:
            if word == "--":
                break
            name = word.split("=", 1)[0]
            if not name.startswith("-") or name in known:
                continue
            try:
                float(name)
            except ValueError:
                raise click.NoSuchOption(name, possibilities=close_matches(name, known), ctx=ctx) from None
        return super().parse_args(ctx, args)


# -- ports -------------------------------------------------------------------------------------

class FloatRange(click.FloatRange):
    """``click.FloatRange`` that also refuses ``nan`` (every comparison with nan is false, so click's
    bounds let it through; ``--time-scale nan`` then failed deep inside with a traceback)."""

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> Any:
        out = super().convert(value, param, ctx)
        if out != out:  # nan
            self.fail(f"{value!r} is not a number", param, ctx)
        return out


class PortType(click.ParamType):  # type: ignore[type-arg]  # generic only since click 8.2
    """A listening port: 1..65535, ``0`` for any free port (the OS picks; the banner prints it), or
    ``off``. One meaning in every command (``wsg sim``, ``wsg demo``), as in the Python API."""

    name = "port"

    def get_metavar(self, param: click.Parameter, ctx: click.Context | None = None) -> str:  # click 8.1 / 8.2
        return "PORT|0|off"

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> int | None:
        if value is None or isinstance(value, int):
            return value
        text = str(value).strip().lower()
        if text in ("off", "none", "no"):
            return None
        try:
            port = int(text, 10)
        except ValueError:
            self.fail(f"{value!r} is not a port: give 1..65535, 0 for any free port, or off", param, ctx)
        if not 0 <= port <= 65535:
            self.fail(f"{port} is not in 0..65535 (0: any free port; off: no interface)", param, ctx)
        return port


PORT = PortType()


# -- common options ----------------------------------------------------------------------------

@dataclasses.dataclass
class Options:
    """What every commander subcommand accepts."""

    url: str
    as_json: bool
    log: CommLog | None
    timeout: float


def _remember_url(ctx: click.Context, param: click.Parameter, value: str | None) -> None:
    if value is not None:
        ctx.meta["pywsg.url"] = value


def common_options(f: F) -> F:
    """``--url``, ``--json``, ``--log``, ``--log-file``, ``--timeout`` (in that order in --help).

    ``--url`` is also an option of ``wsg`` itself: ``wsg --url U monitor`` and ``wsg monitor --url U``
    mean the same, like ``--json`` and ``--log``; the subcommand's wins when both are given.
    """
    f = click.option("--timeout", type=click.FloatRange(min=0.01), default=5.0, show_default=True, metavar="SECONDS",
                     help="Seconds to wait for each reply from the gripper.")(f)
    f = click.option("--log-file", type=click.Path(dir_okay=False, writable=True), metavar="PATH",
                     help="Append the communication log as JSON lines to PATH (read it with `wsg log PATH`).")(f)
    f = click.option("--log", "log_flag", is_flag=True,
                     help="Print the communication log (time, TX/RX, hex, decoded frame) on stderr.")(f)
    f = click.option("--json", "as_json", is_flag=True, help="Machine-readable output (one JSON object).")(f)
    f = click.option("--url", metavar="URL", default=None, expose_value=False, callback=_remember_url,
                     allow_from_autoenv=False,
                     help="Gripper address, as `wsg --url` (default: the one given to wsg, or WSG_URL).")(f)
    return f


def options(ctx: click.Context, as_json: bool, log_flag: bool, log_file: str | None, timeout: float) -> Options:
    root = ctx.find_root().obj or {}
    # `wsg --log move 20` and `wsg move 20 --log` mean the same
    as_json = as_json or bool(root.get("json"))
    log_flag = log_flag or bool(root.get("log"))
    log_file = log_file or root.get("log_file")
    log: CommLog | None = None
    if log_flag or log_file:
        jsonl = None
        if log_file:
            jsonl = Path(log_file).open("a", encoding="utf-8")  # noqa: SIM115 - closed at exit
            ctx.call_on_close(jsonl.close)
        log = CommLog(text=sys.stderr if log_flag else None, jsonl=jsonl)
    url = ctx.meta.get("pywsg.url") or root.get("url") or "tcp://127.0.0.1:1000"
    return Options(url, as_json, log, timeout)


def pop_common(kw: dict[str, Any]) -> tuple[bool, bool, str | None, float]:
    return kw.pop("as_json"), kw.pop("log_flag"), kw.pop("log_file"), kw.pop("timeout")
