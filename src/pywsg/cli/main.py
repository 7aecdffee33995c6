"""``wsg``: the WSG Commander for the terminal.

Subcommands live in their own modules and are imported only when used, so ``wsg --help``
and ``wsg decode`` stay fast. Register a new one in ``_SUBCOMMANDS``: name -> "module:attribute".
"""

from __future__ import annotations

import contextlib
import importlib
import importlib.util
import logging
import os
import signal
import sys

import click

from .. import __version__

_SUBCOMMANDS: dict[str, str] = {
    "decode": "pywsg.cli.decode:decode",
    "sim": "pywsg.cli.sim:sim",
    "plc-demo": "pywsg.cli.plc:plc_demo",
    "demo": "pywsg.cli.demo:demo",
    "world": "pywsg.cli.world:world",
    "proxy": "pywsg.cli.proxy:proxy",
    "replay": "pywsg.cli.replay:replay",
    "gsd": "pywsg.cli.gsd:gsd",
    "commander": "pywsg.cli.commander:commander",
    "ros": "pywsg.cli.ros:ros",
    # driver-backed commander commands (issue 5) register themselves in pywsg.cli.commands
}
_COMMANDER_MODULE = "pywsg.cli.commands"

DEFAULT_URL = "tcp://127.0.0.1:1000"

#: The sections of ``wsg --help``; a command in none of them is listed under "other".
SECTIONS: dict[str, tuple[str, ...]] = {
    "Motion": ("home", "move", "grip", "release", "stop", "fast-stop", "ack"),
    "State": ("state", "info", "width", "speed", "force", "gripper-state", "flags", "temp", "limits", "stats",
              "monitor"),
    "Configuration": ("accel", "force-limit", "soft-limits", "overdrive", "tare", "tag", "finger"),
    "Tools": ("commander", "send", "loop", "log", "decode", "sim", "demo", "plc-demo", "gsd", "world", "proxy",
              "replay", "ros"),
}


# -- logging -----------------------------------------------------------------------------------

def configure_logging(verbose: int) -> None:
    """Log lines on stderr: warnings only as ``warning: text``; with -v (info) or -vv (debug) every
    line with its time, level and logger, so an informational line never reads "warning:"."""
    if verbose:
        level = logging.INFO if verbose == 1 else logging.DEBUG
        logging.basicConfig(level=level, format="%(asctime)s %(levelname)s %(name)s: %(message)s", force=True)
        logging.getLogger("pywsg").setLevel(level)
        return
    logging.basicConfig(level=logging.WARNING, format="warning: %(message)s", force=True)
    # the driver's WARNING on a lost connection would repeat the error line the command prints
    logging.getLogger("pywsg.client").setLevel(logging.ERROR)
    # pymodbus logs transport failures (and its last frames) at ERROR/CRITICAL; our error line says it
    logging.getLogger("pymodbus").setLevel(logging.CRITICAL + 1)


class SuggestingGroup(click.Group):
    """A click group that answers a mistyped command name with the names it is close to."""

    def resolve_command(self, ctx: click.Context, args: list[str]) -> tuple[str | None, click.Command | None,
                                                                             list[str]]:
        """click's lookup, plus "Did you mean 'move'?" for a mistyped command name (difflib)."""
        name = click.utils.make_str(args[0])
        if self.get_command(ctx, name) is None and not ctx.resilient_parsing and not name.startswith("-"):
            from .runner import close_matches

            near = close_matches(name, self.list_commands(ctx))
            if near:
                ctx.fail(f"No such command {name!r}. Did you mean " + " or ".join(repr(n) for n in near) + "?")
        return super().resolve_command(ctx, args)


def _option_names(params: list[click.Parameter]) -> tuple[set[str], set[str]]:
    """The option names among ``params``, and those of them that take a value."""
    names: set[str] = set()
    valued: set[str] = set()
    for p in params:
        if isinstance(p, click.Option):
            names.update(p.opts, p.secondary_opts)
            if not p.is_flag and not p.count:
                valued.update(p.opts)
    return names, valued


class EitherSideGroup(SuggestingGroup):
    """Global options work on either side of the command name (issue 34 item 6).

    ``wsg --timeout 2 state`` and ``wsg state -v`` mean ``wsg state --timeout 2`` and ``wsg -v state``:
    before click parses, an option ``wsg`` does not know that stands before the command name moves
    behind it, an option of ``wsg`` the command does not have itself (``-v``, ``--log``, ``--json``,
    ...) moves in front of it, and ``--json``/``--log``/``--log-file`` before the name go to a command
    that has its own (``wsg --json decode X``). The command's own option wins where both have one.
    """

    def parse_args(self, ctx: click.Context, args: list[str]) -> list[str]:
        if not ctx.resilient_parsing:
            args = self._either_side(ctx, args)
        return super().parse_args(ctx, args)

    def _either_side(self, ctx: click.Context, args: list[str]) -> list[str]:
        mine, mine_valued = _option_names(self.get_params(ctx))
        commands = set(self.list_commands(ctx))
        front: list[str] = []
        behind: list[str] = []  # options for the command, found before its name
        i = 0
        while i < len(args) and args[i] not in commands:
            word = args[i]
            if word == "--" or not word.startswith("-"):
                return args  # no command name where one could be: leave it to click's messages
            name = word.split("=", 1)[0]
            ours = name in mine or _is_verbose(word)
            target = front if ours else behind
            target.append(word)
            i += 1
            nxt = args[i] if i < len(args) else None
            # a value follows: one of ours that takes it, or for the command's option a word that is
            # neither an option nor a command name (``--timeout 2``)
            takes = name in mine_valued if ours else nxt is not None and not nxt.startswith("-")
            if "=" not in word and takes and nxt is not None and nxt not in commands:
                target.append(nxt)
                i += 1
        if i >= len(args):
            return args
        cmd = self.get_command(ctx, args[i])
        if cmd is None:
            return args
        theirs, theirs_valued = _option_names(cmd.get_params(ctx))
        # ``wsg --json decode X`` is ``wsg decode --json X``: an option of the same meaning on both
        # sides goes to a command that has it (a command that has none reads wsg's, see runner.options)
        kept: list[str] = []
        k = 0
        while k < len(front):
            word = front[k]
            name = word.split("=", 1)[0]
            n = 2 if name in mine_valued and "=" not in word and k + 1 < len(front) else 1
            (behind if name in SAME_MEANING and name in theirs else kept).extend(front[k:k + n])
            k += n
        front = kept
        rest: list[str] = []
        j = i + 1
        while j < len(args):
            word = args[j]
            name = word.split("=", 1)[0]
            if word == "--":
                rest.extend(args[j:])
                break
            if name in theirs:
                rest.append(word)
                if name in theirs_valued and "=" not in word and j + 1 < len(args):
                    rest.append(args[j + 1])
                    j += 1
            elif name in mine or _is_verbose(word):
                front.append(word)
                if name in mine_valued and "=" not in word and j + 1 < len(args):
                    front.append(args[j + 1])
                    j += 1
            else:
                rest.append(word)
            j += 1
        return [*front, args[i], *behind, *rest]


SAME_MEANING = frozenset({"--json", "--log", "--log-file"})
"""Options of ``wsg`` that mean the same as a command's own option of that name."""


def _is_verbose(word: str) -> bool:
    return len(word) > 1 and word[0] == "-" and set(word[1:]) == {"v"}


class LazyGroup(EitherSideGroup):
    """A click group that imports each subcommand's module on first use."""

    def _commander(self) -> dict[str, click.Command]:
        try:
            module = importlib.import_module(_COMMANDER_MODULE)
        except ModuleNotFoundError as exc:
            if exc.name == _COMMANDER_MODULE:
                return {}
            raise
        commands: dict[str, click.Command] = module.COMMANDS
        return commands

    def list_commands(self, ctx: click.Context) -> list[str]:
        names = set(super().list_commands(ctx)) | set(self._available()) | set(self._commander())
        return sorted(names)

    def _available(self) -> list[str]:
        out = []
        for name, target in _SUBCOMMANDS.items():
            spec = importlib.util.find_spec(target.split(":")[0])
            if spec is not None:
                out.append(name)
        return out

    def format_commands(self, ctx: click.Context, formatter: click.HelpFormatter) -> None:
        """The subcommands in sections (motion, state, configuration, tools), each in the order people
        reach for them."""
        found: dict[str, click.Command] = {}
        for name in self.list_commands(ctx):
            cmd = self.get_command(ctx, name)
            if cmd is not None and not cmd.hidden:
                found[name] = cmd
        limit = formatter.width - 6 - max((len(n) for n in found), default=0)
        placed: set[str] = set()
        for title, names in [*SECTIONS.items(), ("Other", tuple(sorted(found)))]:
            rows = [(n, found[n].get_short_help_str(limit)) for n in names if n in found and n not in placed]
            placed.update(n for n, _ in rows)
            if rows:
                with formatter.section(title):
                    formatter.write_dl(rows)

    def get_command(self, ctx: click.Context, cmd_name: str) -> click.Command | None:
        if cmd_name in _SUBCOMMANDS and cmd_name in self._available():
            module_name, attr = _SUBCOMMANDS[cmd_name].split(":")
            cmd: click.Command = getattr(importlib.import_module(module_name), attr)
            return cmd
        found = self._commander().get(cmd_name)
        if found is not None:
            return found
        return super().get_command(ctx, cmd_name)


@click.group(cls=LazyGroup, context_settings={"help_option_names": ["-h", "--help"], "max_content_width": 100})
@click.option(
    "--url", envvar="WSG_URL", default=DEFAULT_URL, show_default=True, metavar="URL",
    help="Gripper address: tcp://HOST[:1000], udp://HOST[:1500][?reply_port=1501], "
    "serial:///dev/ttyUSB0?baudrate=115200, can://can0?interface=socketcan (or set WSG_URL).",
)
@click.option("-v", "--verbose", count=True, help="More log output (-v info, -vv debug).")
@click.option("--log", "log_flag", is_flag=True,
              help="Communication log on stderr for the command that follows (same as its own --log).")
@click.option("--log-file", type=click.Path(dir_okay=False, writable=True), metavar="PATH",
              help="Append the communication log as JSON lines to PATH (same as the command's --log-file).")
@click.option("--json", "as_json", is_flag=True, help="JSON output for the command that follows.")
@click.version_option(__version__, prog_name="wsg")
@click.pass_context
def cli(ctx: click.Context, url: str, verbose: int, log_flag: bool, log_file: str | None, as_json: bool) -> None:
    """Drive, simulate and inspect Weiss Robotics / SCHUNK WSG grippers.

    Units everywhere: widths in mm, speeds in mm/s, accelerations in mm/s², forces in N.
    """
    configure_logging(min(verbose, 2))
    ctx.ensure_object(dict)
    ctx.obj["url"] = url
    ctx.obj["verbose"] = verbose
    ctx.obj["log"] = log_flag
    ctx.obj["log_file"] = log_file
    ctx.obj["json"] = as_json


def main() -> None:
    """Console entry point: exits 128 + N on signal N (130 on Ctrl-C) after closing the gripper cleanly."""
    from . import signals

    signals.install()
    try:
        cli(prog_name="wsg", auto_envvar_prefix=None if os.environ.get("WSG_NO_ENV") else "WSG")
    except signals.Interrupted as exc:
        with contextlib.suppress(OSError):
            click.echo(f"wsg: stopped by {signal.Signals(exc.signum).name}", err=True)
        sys.exit(exc.exit_code)
