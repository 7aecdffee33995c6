"""Run virtual grippers on real interfaces: the engine of ``wsg sim`` and a Python API for tests.

::

    from pywsg.server import SimServer

    async with SimServer(tcp_port=0, udp_port=0, serial="pty") as sim:
        g = sim.grippers[0]
        print(g.tcp_port, g.udp_port, g.serial_path)   # bound ports, pty device path
        # ... connect a client to tcp://127.0.0.1:{g.tcp_port}

In the Python API a port of ``0`` means "any free port" and ``None`` means "interface off" (on the
command line: ``0`` and ``off``). With ``count=N`` there are N independent grippers; fixed ports count up
from the given one (gripper ``i`` on ``port + i``), port 0 gives each its own free port.
"""

from __future__ import annotations

import asyncio
import contextlib
import errno
import gc
import importlib
import inspect
import logging
import os
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from .can_bus import CanServer
from .conncap import FD_RESERVE, fd_limit, open_fds
from .device_api import GripperLike
from .limits import DEFAULT_LIMITS, Limits
from .scheduler import DeviceRunner, Scheduler, get_scheduler
from .serial_port import SerialServer
from .tcp import TcpServer
from .udp import UdpServer

log = logging.getLogger("pywsg.server.sim")

GripperFactory = Callable[[str, Any, Any], GripperLike]
"""(model, settings or None, clock or None) -> gripper; defaults to :class:`pywsg.device.VirtualGripper`."""


class SimError(RuntimeError):
    """A sim interface could not be started (port taken, optional part missing, bad option)."""


@dataclass(frozen=True)
class SimOptions:
    """What to serve. Ports: ``None`` = off, ``0`` = any free port."""

    model: str = "wsg50"
    host: str = "127.0.0.1"
    tcp_port: int | None = 0
    udp_port: int | None = 0
    udp_reply_port: int | None = None
    """UDP replies go to the sender's IP on this port (factory setting 1501); None: the sender's port."""
    serial: str | None = None
    """``"pty"`` for a pseudo-terminal, a device path for a real port, None for none."""
    baudrate: int = 115200
    can_channel: str | None = None
    """python-can channel (inferred mapping, see docs/sim.md); None: no CAN."""
    can_interface: str = "virtual"
    can_rx_id: int = 0x01
    """CAN identifier the sim receives requests on (a client's ``request_id``), 11 bits."""
    can_tx_id: int = 0x02
    """CAN identifier the sim sends replies on (a client's ``reply_id``), 11 bits."""
    can_bitrate: int = 500_000
    """Bit rate in bit/s for a hardware CAN interface (the virtual bus has none)."""
    modbus_port: int | None = None
    profinet: str | None = None
    """Network interface for the PROFINET IO device (needs root or CAP_NET_RAW); None: off."""
    profinet_name: str | None = None
    """PROFINET NameOfStation; None: the stored (permanent) one, else unnamed until a DCP Set."""
    profinet_ip: str | None = None
    """PROFINET IP suite ``IP/PREFIX`` or ``IP/MASK``; None: the stored one, else none until a DCP Set."""
    profibus: str | None = None
    """PROFIBUS DP slave: ``"pty"`` for a new pseudo-terminal, a serial device path, None for none."""
    profibus_address: int | None = None
    """Station address 0..125; None: the stored one (Settings → Command Interface), else 7."""
    profibus_baudrate: int | None = 19200
    """Baud rate in bit/s (one the GSD declares; nominal on a pty); None: detected (a real port)."""
    web_port: int | None = None
    settings: Path | None = None
    """Settings file: loaded at start when it exists, saved at a clean stop."""
    count: int = 1
    limits: Limits = DEFAULT_LIMITS
    clock: Any = None
    """Injected clock for every gripper (tests: ``pywsg.device.ManualClock``); None: real time."""
    factory: GripperFactory | None = None
    web_options: dict[str, Any] = field(default_factory=dict)
    """Extra keyword arguments for ``pywsg.web.app.serve_web``."""


def _default_factory(model: str, settings: Any, clock: Any) -> GripperLike:
    from ..device import VirtualGripper

    kwargs: dict[str, Any] = {}
    if settings is not None:
        kwargs["settings"] = settings
    if clock is not None:
        kwargs["clock"] = clock
    gripper: GripperLike = VirtualGripper(model, **kwargs)
    return gripper


def _nth(port: int | None, i: int) -> int | None:
    if port is None or port == 0:
        return port
    return port + i


def bind_error(what: str, host: str, port: int, option: str, exc: OSError) -> SimError:
    """A listening socket that could not be opened: which address, why, and how to pick another port."""
    why = os.strerror(exc.errno) if exc.errno else str(exc)  # asyncio's bind errors carry a long text
    text = f"{what}: cannot listen on {host}:{port}: {why}"
    if exc.errno == errno.EADDRINUSE:
        text += (f" (another program, perhaps another `wsg sim`, has port {port}): choose another with "
                 f"{option} PORT, or {option} 0 for any free port")
    elif exc.errno == errno.EACCES and 0 < port < 1024:
        text += (" (ports below 1024 need root or the sysctl net.ipv4.ip_unprivileged_port_start; in a "
                 "container: --sysctl net.ipv4.ip_unprivileged_port_start=0, see docs/container.md)")
    return SimError(text)


async def _serve_optional(module: str, func: str, what: str, *args: Any, option: str = "", **kwargs: Any) -> Any:
    """Import ``module.func`` only now (optional extras) and await it with the keywords it takes."""
    try:
        mod = importlib.import_module(module)
        serve = getattr(mod, func)
    except (ImportError, AttributeError) as exc:
        raise SimError(f"{what} is not available ({module}.{func}: {exc}); leave its port off") from exc
    params = inspect.signature(serve).parameters
    if not any(p.kind is p.VAR_KEYWORD for p in params.values()):
        kwargs = {k: v for k, v in kwargs.items() if k in params}
    try:
        return await serve(*args, **kwargs)
    except OSError as exc:
        if option and len(args) >= 3:  # (gripper, host, port, ...): a listening server
            raise bind_error(what, str(args[1]), int(args[2]), option, exc) from exc
        raise SimError(f"{what}: {exc.strerror or exc}") from exc


def _bound_port(obj: Any) -> int | None:
    """The port a Modbus/web server object is bound to (tolerates a few shapes)."""
    for attr in ("port", "bound_port"):
        value = getattr(obj, attr, None)
        if isinstance(value, int):
            return value
    return None


@dataclass
class SimGripper:
    """One virtual gripper and the interfaces that serve it."""

    index: int
    gripper: GripperLike
    runner: DeviceRunner
    host: str
    tcp: TcpServer | None = None
    udp: UdpServer | None = None
    serial: SerialServer | None = None
    can: CanServer | None = None
    modbus: Any = None
    profinet: Any = None
    profibus: Any = None
    controller: Any = None   # the one FieldbusController every bus of this gripper feeds
    """The gripper's one FieldbusController, shared by Modbus/TCP, PROFINET and PROFIBUS."""
    web: Any = None
    modbus_port: int | None = None
    web_port: int | None = None

    def fieldbus_controller(self) -> Any:
        """The gripper's one :class:`~pywsg.fieldbus.controller.FieldbusController` (``controller``),
        made when its first bus starts; Modbus/TCP, PROFINET and PROFIBUS adapters all receive it."""
        if self.controller is None:
            from ..fieldbus.controller import FieldbusController

            device: Any = self.gripper   # a VirtualGripper (GripperLike is what the transports need)
            self.controller = FieldbusController(device)
        return self.controller

    @property
    def tcp_port(self) -> int | None:
        return self.tcp.port if self.tcp else None

    @property
    def udp_port(self) -> int | None:
        return self.udp.port if self.udp else None

    @property
    def serial_path(self) -> str | None:
        return self.serial.path if self.serial else None

    @property
    def tcp_url(self) -> str | None:
        return self.tcp.address if self.tcp else None

    @property
    def udp_url(self) -> str | None:
        return self.udp.address if self.udp else None

    @property
    def serial_url(self) -> str | None:
        return self.serial.address if self.serial else None

    def info(self) -> dict[str, str]:
        """Interface -> address of what this gripper serves (for the web interface)."""
        out: dict[str, str] = {}
        if self.tcp:
            out["tcp"] = self.tcp.address
        if self.udp:
            out["udp"] = self.udp.address
        if self.serial:
            out["serial"] = self.serial.address
        if self.can:
            out["can"] = self.can.address
        if self.modbus is not None:
            out["modbus"] = f"modbus-tcp://{self.host}:{self.modbus_port}"
        if self.profinet is not None:
            out["profinet"] = self.profinet.url()
        if self.profibus is not None:
            out["profibus"] = self.profibus.url
        return out

    def lines(self) -> list[str]:
        """One line per interface, as ``wsg sim`` prints them."""
        tag = f"gripper {self.index}: "
        out = []
        if self.tcp:
            out.append(f"{tag}TCP      {self.tcp.address}")
        if self.udp:
            extra = "" if self.udp.reply_port is not None else " (replies to the sender's port)"
            out.append(f"{tag}UDP      {self.udp.address}{extra}")
        if self.serial:
            out.append(f"{tag}serial   {self.serial.address}")
        if self.can:
            out.append(f"{tag}CAN      {self.can.address} (inferred mapping)")
        if self.modbus is not None:
            out.append(f"{tag}Modbus   modbus-tcp://{self.host}:{self.modbus_port}")
        if self.profinet is not None:
            out.append(f"{tag}PROFINET {self.profinet.line()}")
        if self.profibus is not None:
            out.append(f"{tag}PROFIBUS {self.profibus.url}")
        if self.web is not None:
            out.append(f"{tag}web      http://{self.host}:{self.web_port}/")
        return out


class SimServer:
    """Starts ``count`` virtual grippers with their interfaces; ``async with`` or start()/close()."""

    def __init__(self, options: SimOptions | None = None, **overrides: Any) -> None:
        self.options = replace(options or SimOptions(), **overrides)
        self.grippers: list[SimGripper] = []
        self.scheduler: Scheduler | None = None
        self._started = False

    # convenience for the common single-gripper case
    def __getitem__(self, i: int) -> SimGripper:
        return self.grippers[i]

    @property
    def tcp_port(self) -> int | None:
        return self.grippers[0].tcp_port

    @property
    def udp_port(self) -> int | None:
        return self.grippers[0].udp_port

    @property
    def serial_path(self) -> str | None:
        return self.grippers[0].serial_path

    @property
    def modbus_port(self) -> int | None:
        return self.grippers[0].modbus_port

    @property
    def web_port(self) -> int | None:
        return self.grippers[0].web_port

    @property
    def gripper(self) -> GripperLike:
        return self.grippers[0].gripper

    def lines(self) -> list[str]:
        return [line for g in self.grippers for line in g.lines()]

    async def __aenter__(self) -> SimServer:
        await self.start()
        return self

    async def __aexit__(self, *exc: object) -> None:
        await self.close()

    def _load_settings(self) -> Any:
        path = self.options.settings
        if path is None:
            return None
        if not Path(path).exists():
            from ..device import Settings

            Settings.clean_temporaries(path)  # a save killed before its first rename
            return None
        from ..device import Settings
        from ..device.settings import SettingsError

        try:
            return Settings.load(path)
        except SettingsError as exc:
            raise SimError(str(exc)) from None

    async def start(self) -> SimServer:
        opts = self.options
        if opts.count < 1:
            raise SimError("count must be at least 1")
        self.scheduler = get_scheduler()
        factory = opts.factory or _default_factory
        settings = self._load_settings()
        self._started = True
        fds = [open_fds()]  # descriptors open before any gripper, then after each of the first two
        try:
            for i in range(opts.count):
                gripper = factory(opts.model, settings, opts.clock)
                runner = DeviceRunner(gripper, self.scheduler)
                sg = SimGripper(i, gripper, runner, opts.host)
                self.grippers.append(sg)
                try:
                    await self._start_one(sg, i)
                except (OSError, SimError) as exc:
                    cause = exc if isinstance(exc, OSError) else exc.__cause__
                    if isinstance(cause, OSError) and cause.errno in (errno.EMFILE, errno.ENFILE):
                        raise self._fd_error(fds, i) from exc
                    raise
                runner.start()
                if i < 2:
                    fds.append(open_fds())
                if i == 1:
                    self._check_fds(fds)
        except BaseException:
            await self.close(save=False)
            raise
        return self

    def _per_gripper(self, fds: list[int | None]) -> int:
        """Descriptors one gripper holds: what the second one opened (the first also opens one-offs)."""
        if len(fds) >= 3 and fds[1] is not None and fds[2] is not None:
            return max(1, fds[2] - fds[1])
        return 6  # TCP, UDP, Modbus/TCP, web, a pty's two ends

    def _fds_text(self, fds: list[int | None]) -> tuple[str, int] | None:
        limit, base = fd_limit(), fds[0]
        if limit is None or base is None:
            return None
        per = self._per_gripper(fds)
        count = self.options.count
        fits = max(0, (limit - FD_RESERVE - base) // per)
        needed = base + per * count + FD_RESERVE
        return (f"--count {count} needs about {needed} file descriptors ({per} per gripper, {FD_RESERVE} kept "
                f"free for connections) but this process may open {limit} (ulimit -n): --count {fits} fits, "
                f"or raise the limit (ulimit -n {needed}) or turn interfaces off (--serial off, --web-port off)",
                fits)

    def _check_fds(self, fds: list[int | None]) -> None:
        """Refuse a --count the descriptor limit cannot hold before binding hundreds of sockets."""
        found = self._fds_text(fds)
        if found is not None and found[1] < self.options.count:
            raise SimError(found[0])

    def _fd_error(self, fds: list[int | None], i: int) -> SimError:
        found = self._fds_text(fds)
        text = found[0] if found is not None else "raise the limit (ulimit -n) or start fewer grippers"
        return SimError(f"gripper {i}: out of file descriptors: {text}")

    async def _start_one(self, sg: SimGripper, i: int) -> None:
        opts = self.options
        g, r = sg.gripper, sg.runner
        tcp_port = _nth(opts.tcp_port, i)
        if tcp_port is not None:
            try:
                sg.tcp = await TcpServer(g, r, opts.host, tcp_port, opts.limits).start()
            except OSError as exc:
                raise bind_error(f"gripper {i}: TCP", opts.host, tcp_port, "--tcp-port", exc) from exc
        udp_port = _nth(opts.udp_port, i)
        if udp_port is not None:
            try:
                sg.udp = await UdpServer(g, r, opts.host, udp_port, opts.udp_reply_port, opts.limits).start()
            except OSError as exc:
                raise bind_error(f"gripper {i}: UDP", opts.host, udp_port, "--udp-port", exc) from exc
            self._warn_reply_port(sg.udp, i)
        if opts.serial:
            path = opts.serial if opts.serial == "pty" or opts.count == 1 else f"{opts.serial}{i}"
            try:
                sg.serial = await SerialServer(g, r, path, opts.baudrate, opts.limits).start()
            except OSError as exc:
                raise SimError(f"gripper {i}: cannot open serial port {path}: {exc}") from exc
        if opts.can_channel:
            channel = opts.can_channel if opts.count == 1 else f"{opts.can_channel}{i}"
            sg.can = await CanServer(
                g, r, channel, opts.can_interface, opts.can_rx_id, opts.can_tx_id, opts.can_bitrate
            ).start()
        modbus_port = _nth(opts.modbus_port, i)
        if modbus_port is not None:
            sg.modbus = await _serve_optional(
                "pywsg.fieldbus.modbus.server", "serve_modbus", "the Modbus/TCP server", g, opts.host, modbus_port,
                option="--modbus-port", controller=sg.fieldbus_controller(),
                max_connections=opts.limits.modbus_connections, idle_timeout=opts.limits.idle_timeout,
            )
            sg.modbus_port = _bound_port(sg.modbus) or modbus_port
        if opts.profibus:
            await self._start_profibus(sg, i)
        if opts.profinet is not None:
            sg.profinet = await self._start_profinet(sg, i)
        web_port = _nth(opts.web_port, i)
        if web_port is not None:
            extra: dict[str, Any] = {
                "sim_info": sg.info(),
                "fieldbus": sg.controller,
                "settings_path": str(opts.settings) if opts.settings else None,
                "max_connections": opts.limits.web_connections,
                "idle_timeout": opts.limits.idle_timeout,
            }
            extra.update(opts.web_options)
            sg.web = await _serve_optional(
                "pywsg.web.app", "serve_web", "the web interface", g, opts.host, web_port, option="--web-port",
                **extra
            )
            sg.web_port = _bound_port(sg.web) or web_port

    async def _start_profinet(self, sg: SimGripper, i: int) -> Any:
        opts = self.options
        if opts.count > 1:
            raise SimError("--profinet serves one gripper on one interface: use --count 1")
        try:
            from ..fieldbus.profinet import ProfinetError, serve_profinet
            from ..fieldbus.profinet.station import parse_ip_suite
        except ImportError as exc:
            raise SimError(f"PROFINET is not available: {exc}") from exc
        try:
            suite = parse_ip_suite(opts.profinet_ip) if opts.profinet_ip else None
        except ValueError as exc:
            raise SimError(f"--profinet-ip: {exc}") from None
        controller = sg.fieldbus_controller()
        store = None if opts.settings is None else Path(opts.settings).with_name(
            Path(opts.settings).stem + ".interface.json")   # beside the settings, as the web interface keeps it
        try:
            return await serve_profinet(sg.gripper, str(opts.profinet), controller, station_name=opts.profinet_name,
                                        ip=suite, store_path=store)
        except ProfinetError as exc:
            raise SimError(str(exc)) from None
    async def _start_profibus(self, sg: SimGripper, i: int) -> None:
        from ..fieldbus.profibus.station import AddressStore

        opts = self.options
        store = AddressStore.beside(opts.settings)
        stored = store.load() + i     # also reads the stored No_Add_Chg
        address = stored if opts.profibus_address is None else opts.profibus_address
        line = opts.profibus or "pty"
        path = line if line == "pty" or opts.count == 1 else f"{line}{i}"
        from ..fieldbus.profibus.line import ProfibusAdapter

        try:
            sg.profibus = await ProfibusAdapter(sg.fieldbus_controller(), path, address, opts.profibus_baudrate,
                                                on_address_change=store.save if i == 0 else None,
                                                address_locked=store.locked and i == 0).start()
        except ValueError as exc:
            raise SimError(f"gripper {i}: PROFIBUS: {exc}") from None
        except OSError as exc:   # pyserial nests the OS error in its own message: name the cause once
            why = getattr(exc.__context__, "strerror", None) or exc.strerror or exc
            raise SimError(f"gripper {i}: cannot open PROFIBUS line {path}: {why} "
                           "(--profibus pty for a new pseudo-terminal)") from exc
        sg.controller.attach_bus(sg.profibus)

    def _warn_reply_port(self, udp: UdpServer, i: int) -> None:
        """A reply port that is a UDP port of this sim: no gripper can answer clients on this host."""
        opts = self.options
        reply = opts.udp_reply_port
        if i != 0 or reply is None or opts.udp_port in (None, 0):
            return
        if opts.udp_port <= reply < opts.udp_port + opts.count:
            log.warning(
                "UDP reply port %d is gripper %d's own UDP port: a gripper never sends to a UDP port of its "
                "own process (a reply loop), so UDP clients on this host get no answer; use "
                "--udp-reply-port 0 (answer the sender's port) or a port outside %d..%d",
                reply, reply - opts.udp_port, opts.udp_port, opts.udp_port + opts.count - 1)

    @staticmethod
    async def _close_one(sg: SimGripper) -> None:
        sg.runner.stop()
        for part in (sg.web, sg.profinet, sg.profibus, sg.modbus, sg.can, sg.serial, sg.udp, sg.tcp):
            if part is None:
                continue
            with contextlib.suppress(Exception):
                await part.close()
        if sg.controller is not None:   # after its buses: none feeds it any more
            with contextlib.suppress(Exception):
                sg.controller.close()
            sg.controller = None

    async def close(self, save: bool = True) -> None:
        """Stop every interface (sockets closed, sessions closed) and save the settings file."""
        if not self._started:
            return
        self._started = False
        # every gripper at once: a web interface takes ~0.2 s to stop (uvicorn looks at its exit flag
        # every 0.1 s), so one after the other 200 grippers took 36 s, past a supervisor's stop timeout
        await asyncio.gather(*(self._close_one(sg) for sg in self.grippers))
        path = self.options.settings
        if save and path is not None and self.grippers:
            settings = getattr(self.grippers[0].gripper, "settings", None)
            if settings is not None and hasattr(settings, "save"):
                try:
                    settings.save(path)
                except OSError as exc:
                    raise SimError(
                        f"{path}: cannot save settings: {exc.strerror or exc}; this run's changes are lost "
                        "(--settings must name a file in a writable directory)"
                    ) from None
        await asyncio.sleep(0)


async def run_sim(
    options: SimOptions,
    stop: asyncio.Event | None = None,
    echo: Callable[[str], None] = print,
    on_start: Callable[[SimServer], None] | None = None,
) -> SimServer:
    """Run until ``stop`` is set or SIGINT/SIGTERM arrives; prints one line per interface.
    ``on_start(sim)`` runs on the loop once every interface is up (world set-up, scenarios)."""
    import signal

    stop = stop or asyncio.Event()
    loop = asyncio.get_running_loop()
    installed = []
    for sig in (signal.SIGINT, signal.SIGTERM):
        try:
            loop.add_signal_handler(sig, stop.set)
            installed.append(sig)
        except (NotImplementedError, RuntimeError, ValueError):  # not the main thread / platform
            pass
    sim = SimServer(options)
    try:
        await sim.start()
        if on_start is not None:
            on_start(sim)
        # What start-up made (catalog, web app, ...) lives until exit: freezing it keeps the garbage
        # collector's full passes from scanning it, which took 40-80 ms each under a flood of requests.
        gc.freeze()
        for line in sim.lines():
            echo(line)
        await stop.wait()
        echo("stopping")
    finally:
        await sim.close()
        for sig in installed:
            loop.remove_signal_handler(sig)
    return sim
