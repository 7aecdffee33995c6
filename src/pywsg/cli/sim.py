"""``wsg sim``: serve virtual grippers on TCP, UDP, serial (pty), CAN, Modbus/TCP, PROFIBUS DP and the web."""

from __future__ import annotations

import asyncio
import json
import re
from pathlib import Path
from typing import Any

import click

from .runner import PORT, FloatRange


class _CanId(click.ParamType):  # type: ignore[type-arg]  # generic only since click 8.2
    """An 11-bit CAN identifier, decimal or 0x.. (the sim's CAN side uses standard identifiers)."""

    name = "id"

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> int:
        if isinstance(value, int):
            ident = value
        else:
            try:
                ident = int(str(value), 0)
            except ValueError:
                self.fail(f"{value!r} is not an integer (decimal or 0x..)", param, ctx)
        if not 0 <= ident <= 0x7FF:
            self.fail(f"{value} is not an 11-bit CAN identifier (0..0x7FF)", param, ctx)
        return ident


CAN_ID = _CanId()

MODELS = ("wsg50", "wsg32", "wsg25", "wsg70")


def _serial(value: str) -> str | None:
    return None if value.lower() in ("0", "off", "none", "") else value


def _scaled_clock(k: float) -> Any:
    """A :class:`~pywsg.device.ScaledClock` for ``--time-scale K`` (None: real time)."""
    if k == 1:
        return None
    from ..device.clock import ScaledClock

    return ScaledClock(k)


def _run(coro: Any, use_uvloop: bool | None) -> Any:
    """Run with uvloop when asked (or by default when installed), else stock asyncio."""
    if use_uvloop is not False:
        try:
            import uvloop
        except ImportError:
            if use_uvloop:
                raise click.UsageError("--uvloop needs uvloop: pip install 'pywsg[fast]'") from None
        else:
            return uvloop.run(coro)
    return asyncio.run(coro)


def _loopback(host: str) -> bool:
    from ..web.security import is_loopback_host  # only with the web interface on: pywsg[web] is there

    return is_loopback_host(host)


def _web_password(given: str | None, path: Path | None) -> str | None:
    """The web password from --web-password or the first line of --web-password-file (a mounted secret;
    the line end is not part of it). 1..256 characters, as the web interface takes it."""
    if given is not None and path is not None:
        raise click.UsageError("give --web-password or --web-password-file (WSG_WEB_PASSWORD or "
                               "WSG_WEB_PASSWORD_FILE), not both")
    if path is not None:
        try:
            lines = path.read_text(encoding="utf-8").splitlines()
        except (OSError, UnicodeDecodeError) as exc:
            raise click.BadParameter(f"{path}: cannot read: {getattr(exc, 'strerror', None) or exc}",
                                     param_hint="--web-password-file") from None
        given = lines[0] if lines else ""
        hint = "--web-password-file"
    else:
        hint = "--web-password"
    if given is not None and not 1 <= len(given) <= 256:
        raise click.BadParameter("the web password must be 1..256 characters", param_hint=hint)
    return given


_BANNER = re.compile(r"gripper (\d+): (\S+)\s+(\S+)(.*)")


def _json_line(line: str) -> str:
    """A banner line (``gripper 0: TCP      tcp://127.0.0.1:1000``) as one JSON object."""
    m = _BANNER.fullmatch(line)
    if m is None:
        return json.dumps({"event": line})
    data = {"event": "interface", "gripper": int(m[1]), "kind": m[2].lower(), "url": m[3]}
    if m[4].strip():
        data["note"] = m[4].strip(" ()")
    return json.dumps(data)


@click.command("sim")
@click.option("--model", type=click.Choice(MODELS), default="wsg50", show_default=True, help="Device profile.")
@click.option("--host", default="127.0.0.1", show_default=True, help="Address to bind (0.0.0.0: all).")
@click.option("--tcp-port", type=PORT, default="1000", show_default=True,
              help="TCP command interface (0: any free port, off: none).")
@click.option("--udp-port", type=PORT, default="1500", show_default=True,
              help="UDP command interface, local port (0: any free port, off: none).")
@click.option("--udp-reply-port", type=click.IntRange(0, 65535), default=1501, show_default=True,
              help="UDP replies go to the client's address on this port (0: back to the client's own port, "
              "as in a URL's reply_port=0).")
@click.option("--serial", "serial_port", default="pty", show_default=True, metavar="pty|PATH|off",
              help="Serial interface: a new pseudo-terminal, an existing serial device, or off.")
@click.option("--baudrate", type=int, default=115200, show_default=True, help="Baud rate for a serial PATH.")
@click.option("--can", "can_channel", default=None, metavar="CHANNEL",
              help="CAN interface on this python-can channel (inferred mapping, see docs/sim.md).")
@click.option("--can-interface", default="virtual", show_default=True, help="python-can interface.")
@click.option("--can-rx-id", type=CAN_ID, default="0x01", show_default=True, metavar="ID",
              help="CAN identifier the sim receives requests on (a client's request_id), 11 bits, e.g. 0x10.")
@click.option("--can-tx-id", type=CAN_ID, default="0x02", show_default=True, metavar="ID",
              help="CAN identifier the sim sends replies on (a client's reply_id), 11 bits.")
@click.option("--can-bitrate", type=click.IntRange(min=1), default=500_000, show_default=True, metavar="BIT/S",
              help="CAN bit rate for a hardware interface (ignored by the virtual bus).")
@click.option("--modbus-port", type=PORT, default="off", show_default=True,
              help="Modbus/TCP fieldbus interface (0: any free port; the standard 502 needs root).")
@click.option("--profinet", "profinet_iface", default=None, metavar="IFACE",
              help="PROFINET IO device on this network interface (a spare NIC to a PLC, or a veth/bridge to a "
              "soft PLC; needs root or CAP_NET_RAW; see docs/fieldbus.md). The host's addresses are not changed.")
@click.option("--profinet-name", default=None, metavar="NAME",
              help="PROFINET NameOfStation (default: the stored one; else unnamed until a controller sets it by DCP).")
@click.option("--profinet-ip", default=None, metavar="IP/PREFIX[,GATEWAY]",
              help="PROFINET IP suite, e.g. 192.168.0.20/24 (default: the stored one; else none until set by DCP).")
@click.option("--profibus", "profibus_line", default="off", show_default=True, metavar="pty|PATH|off",
              help="PROFIBUS DP slave (Ident 5555h, WEIS5555.gsd): a new pseudo-terminal for a master on this "
              "machine, a serial device such as a USB RS-485 adapter (/dev/ttyUSB0, 8E1), or off.")
@click.option("--profibus-address", type=click.IntRange(0, 125), default=None, metavar="0..125",
              help="PROFIBUS station address [default: the stored one (Settings -> Command Interface), else 7].")
@click.option("--profibus-baudrate", default="19200", show_default=True, metavar="BIT/S|auto",
              help="PROFIBUS baud rate, one WEIS5555.gsd declares (9600 ... 1500000); nominal on a pty. "
              "auto: detect the master's rate (a serial device only).")
@click.option("--web-port", type=PORT, default="8080", show_default=True,
              help="Web interface (0: any free port, off: none).")
@click.option("--web-password", envvar="WSG_WEB_PASSWORD", default=None, metavar="PASSWORD",
              help="Password of the web interface and the world API (as 'Authorization: Bearer PASSWORD') "
              "[env WSG_WEB_PASSWORD]. Off loopback without one, a password is made and printed once.")
@click.option("--web-password-file", envvar="WSG_WEB_PASSWORD_FILE", default=None, metavar="PATH",
              type=click.Path(dir_okay=False, path_type=Path),
              help="Read the web password from this file, e.g. a mounted secret (its first line) "
              "[env WSG_WEB_PASSWORD_FILE].")
@click.option("--require-password", is_flag=True,
              help="Off loopback, refuse to start without --web-password or --web-password-file instead of "
              "making one (the container image sets this) [env WSG_SIM_REQUIRE_PASSWORD=1].")
@click.option("--web-allowed-host", "web_allowed_hosts", multiple=True, metavar="NAME",
              help="A further host name the web interface may be reached by (repeatable). Loopback names and the "
              "bound address are always allowed; any other Host header is refused (DNS rebinding guard).")
@click.option("--max-modbus-connections", type=click.IntRange(1, 1000), default=32, show_default=True,
              help="Modbus/TCP masters at a time per gripper; more are refused.")
@click.option("--max-web-connections", type=click.IntRange(1, 1000), default=64, show_default=True,
              help="Open HTTP/WebSocket connections at a time; more are refused.")
@click.option("--web-request-rate", type=FloatRange(0, 100000), default=20.0, show_default=True,
              metavar="PER_S", help="Web requests per second per client address on average (0: no limit); "
              "over it a request is answered 429 Too Many Requests.")
@click.option("--web-request-burst", type=click.IntRange(1, 1000000), default=200, show_default=True,
              help="Web requests a client address may make at once before --web-request-rate applies.")
@click.option("--idle-timeout", type=FloatRange(0, 86400), default=60.0, show_default=True,
              help="Close a Modbus/TCP or web connection after this many seconds without data either way "
                   "(0: never). A polling master is never idle.")
@click.option("--settings", "settings_file", type=click.Path(dir_okay=False, path_type=Path), default=None,
              envvar="WSG_SIM_SETTINGS",
              help="Settings file (JSON): loaded at start if it exists, saved on exit [env WSG_SIM_SETTINGS].")
@click.option("--count", type=click.IntRange(1, 10000), default=1, show_default=True,
              help="Run N independent grippers on consecutive ports.")
@click.option("--time-scale", "time_scale", type=FloatRange(min=0, min_open=True, max=1e6), default=1.0,
              show_default=True, metavar="K",
              help="Run the grippers' time K times faster than real time: motion, homing, heat, auto-update "
              "periods and scenarios (the network and clients' timeouts are not scaled).")
@click.option("--net", "net_faults", multiple=True, metavar="KIND[:K=V,...]",
              help="Start with a network fault on every gripper's interfaces (repeatable), e.g. "
              "latency:ms=200,jitter=50 or drop:p=0.3; wsg world net switches them later (wsg world net --help).")
@click.option("--uvloop/--no-uvloop", "use_uvloop", default=None,
              help="Use uvloop (default: when installed, from pywsg[fast]).")
@click.option("--part", "part_width", type=float, default=None, metavar="WIDTH",
              help="Start with a part of WIDTH mm between the fingers (wsg world: change it later).")
@click.option("--block", "block_width", type=float, default=None, metavar="WIDTH",
              help="Start with a rigid obstacle in the fingers' way at WIDTH mm.")
@click.option("--scenario", "scenario_file", type=click.Path(exists=True, dir_okay=False, path_type=Path),
              default=None, envvar="WSG_SIM_SCENARIO",
              help="Run a scenario (TOML timeline of world events, see docs/testing.md) [env WSG_SIM_SCENARIO].")
@click.option("-v", "--verbose", count=True, help="Log every command (-v) and more (-vv).")
@click.option("--json", "as_json", is_flag=True,
              help='One JSON object per line: {"event": "interface", "gripper": 0, "kind": "tcp", "url": ...}, '
              'then {"event": "stopping"}.')
@click.pass_context
def sim(
    ctx: click.Context,
    model: str,
    host: str,
    tcp_port: int | None,
    udp_port: int | None,
    udp_reply_port: int,
    serial_port: str,
    baudrate: int,
    can_channel: str | None,
    can_interface: str,
    can_rx_id: int,
    can_tx_id: int,
    can_bitrate: int,
    modbus_port: int | None,
    profinet_iface: str | None,
    profinet_name: str | None,
    profinet_ip: str | None,
    profibus_line: str,
    profibus_address: int | None,
    profibus_baudrate: str,
    web_port: int | None,
    web_password: str | None,
    web_password_file: Path | None,
    require_password: bool,
    web_allowed_hosts: tuple[str, ...],
    max_modbus_connections: int,
    max_web_connections: int,
    web_request_rate: float,
    web_request_burst: int,
    idle_timeout: float,
    settings_file: Path | None,
    count: int,
    time_scale: float,
    net_faults: tuple[str, ...],
    use_uvloop: bool | None,
    part_width: float | None,
    block_width: float | None,
    scenario_file: Path | None,
    verbose: int,
    as_json: bool,
) -> None:
    """Run virtual grippers that any WSG client can connect to.

    Prints one line per interface with its address; stops on Ctrl-C or SIGTERM (settings saved,
    sockets closed). With --count N, gripper i listens on each given port + i.

    Every option can also be set by an environment variable WSG_SIM_<OPTION> (--time-scale:
    WSG_SIM_TIME_SCALE); the container image is configured this way (docs/container.md).
    """
    if profinet_name is not None:
        from ..fieldbus.profinet.station import name_error

        problem = name_error(profinet_name)
        if problem:
            raise click.BadParameter(f"{profinet_name!r}: {problem}", param_hint="--profinet-name")
    if can_rx_id == can_tx_id:
        raise click.BadParameter(f"0x{can_tx_id:X} is also --can-rx-id: requests and replies need their own "
                                 "identifiers", param_hint="--can-tx-id")
    from ..server.limits import Limits
    from ..server.sim import SimError, SimOptions, run_sim

    profibus = _serial(profibus_line)
    if profibus is not None:
        from ..fieldbus.profibus.line import check_baudrate

        try:
            if profibus_baudrate != "auto" and not profibus_baudrate.isdigit():
                raise ValueError(f"{profibus_baudrate!r} is neither a rate in bit/s nor auto")
            rate = None if profibus_baudrate == "auto" else int(profibus_baudrate)
            check_baudrate(rate)
            if rate is None and profibus == "pty":
                raise ValueError("auto needs a serial device: a pty has no bit timing")
        except ValueError as exc:
            raise click.BadParameter(str(exc), param_hint="--profibus-baudrate") from None
    else:
        rate = 19200

    parent_verbose = int((ctx.obj or {}).get("verbose", 0)) if isinstance(ctx.obj, dict) else 0
    level = max(verbose, parent_verbose)
    if level:
        from .main import configure_logging

        configure_logging(min(level, 2))

    web = web_port
    if web is not None and ctx.get_parameter_source("web_port") == click.core.ParameterSource.DEFAULT:
        import importlib.util

        try:
            found = importlib.util.find_spec("pywsg.web.app") is not None
        except ImportError:
            found = False
        if not found:
            click.echo("web interface not available (pip install 'pywsg[web]'); running without it", err=True)
            web = None

    password = _web_password(web_password, web_password_file)
    if web is not None and password is None and require_password and not _loopback(host):
        raise click.ClickException(  # one line, no usage text: it ends a container's log
            f"the web interface and world API on {host} need a password: set WSG_WEB_PASSWORD, or mount a "
            "secret file and set WSG_WEB_PASSWORD_FILE to its path (or --web-port off, or --host 127.0.0.1)")
    web_options: dict[str, Any] = {"request_rate": web_request_rate or None, "request_burst": web_request_burst}
    if web_allowed_hosts:
        web_options["allowed_hosts"] = web_allowed_hosts
    if password is not None:
        web_options["password"] = password

    options = SimOptions(
        model=model,
        host=host,
        tcp_port=tcp_port,
        udp_port=udp_port,
        udp_reply_port=udp_reply_port or None,
        serial=_serial(serial_port),
        baudrate=baudrate,
        can_channel=can_channel,
        can_interface=can_interface,
        can_rx_id=can_rx_id,
        can_tx_id=can_tx_id,
        can_bitrate=can_bitrate,
        modbus_port=modbus_port,
        profinet=profinet_iface,
        profinet_name=profinet_name,
        profinet_ip=profinet_ip,
        profibus=profibus,
        profibus_address=profibus_address,
        profibus_baudrate=rate,
        web_port=web,
        settings=settings_file,
        count=count,
        clock=_scaled_clock(time_scale),
        limits=Limits(modbus_connections=max_modbus_connections, web_connections=max_web_connections,
                      idle_timeout=idle_timeout),
        web_options=web_options,
    )

    as_json = as_json or bool((ctx.obj or {}).get("json")) if isinstance(ctx.obj, dict) else as_json

    def echo(line: str) -> None:
        click.echo(_json_line(line) if as_json else line)

    from ..testing.scenario import Scenario, ScenarioError
    from ..testing.world import WorldError

    if net_faults:
        from ..server.netfault import NetFaults
        from .proxy import start_fault

        for spec in net_faults:
            start_fault(NetFaults(), spec)  # a bad --net is a usage error before anything starts
    try:
        scenario = Scenario.load(scenario_file) if scenario_file else None
    except ScenarioError as exc:
        raise click.BadParameter(str(exc), param_hint="--scenario") from None

    def on_start(server: Any) -> None:
        from ..testing.host import setup_world

        def said(i: int, t: float, text: str) -> None:
            if as_json:
                click.echo(json.dumps({"event": "scenario", "gripper": i, "t": round(t, 6), "action": text}))
            else:
                click.echo(f"gripper {i}: scenario t={t:.3f} s: {text}")

        setup_world(server, part=part_width, block=block_width, scenario=scenario, on_action=said)
        if net_faults:
            from ..server.netfault import net_faults as faults_of
            from .proxy import start_fault

            for sg in server.grippers:
                for spec in net_faults:
                    start_fault(faults_of(sg.gripper), spec)

    try:
        _run(run_sim(options, echo=echo, on_start=on_start), use_uvloop)
    except WorldError as exc:
        raise click.BadParameter(str(exc), param_hint="--part/--block") from None
    except SimError as exc:
        raise click.ClickException(str(exc)) from None
    except KeyboardInterrupt:  # signal handlers cover the loop; this covers start-up
        pass
