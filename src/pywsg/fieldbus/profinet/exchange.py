"""PLC side: the image exchange over PROFINET IO, with profinet-py as the IO controller.

profinet-py is GPL-3.0, so it is only an optional extra (``pip install 'pywsg[profinet]'``), imported
lazily here and nowhere else; the device side (:mod:`pywsg.fieldbus.profinet.device`) never uses it.

::

    ex = await ProfinetExchange.open("profinet://eth1/wsg50?cycle_ms=16")
    await ex.write_outputs(bytes([0x08, 0, 0, 0, 0, 0, 0, 0]))   # HOMING
    inputs = await ex.read_inputs()                                 # 12 bytes
    await ex.close()

The AR is built from pywsg's own GSDML (slot 1: the WSG module, 12 input / 8 output bytes). The
controller needs a raw socket (root or CAP_NET_RAW) and UDP port 34964 on the host it runs on.
"""

from __future__ import annotations

import asyncio
import importlib.resources
import logging
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any
from urllib.parse import parse_qs, urlsplit

from ..exchange import FieldbusConnectionError

log = logging.getLogger(__name__)

WSG_SLOT, WSG_SUBSLOT = 1, 1
DEFAULT_CYCLE_MS = 16
HOLD_MS = 200
GSDML_NAME = "GSDML-V2.31-Weiss Robotics-WSG-20140401.gsdml"   # 003 §3.1


class ProfinetUnavailable(FieldbusConnectionError):
    """profinet-py (the optional extra ``profinet``) is not installed."""


def _profinet() -> Any:
    try:
        import profinet
    except ImportError:
        raise ProfinetUnavailable(
            "the PROFINET controller needs profinet-py (GPL-3.0, an optional extra): pip install 'pywsg[profinet]'"
        ) from None
    return profinet


@dataclass(frozen=True)
class ProfinetUrl:
    """``profinet://IFACE/STATION[?cycle_ms=16&timeout=10]``."""

    iface: str
    station: str
    cycle_ms: int = DEFAULT_CYCLE_MS
    timeout: float = 10.0

    @classmethod
    def parse(cls, url: str) -> ProfinetUrl:
        parts = urlsplit(url)
        station = parts.path.strip("/")
        if parts.scheme != "profinet" or not parts.netloc or not station:
            raise ValueError(f"{url!r}: expected profinet://IFACE/STATION, e.g. profinet://eth1/wsg50")
        query = parse_qs(parts.query)
        try:
            cycle = int(query.get("cycle_ms", [DEFAULT_CYCLE_MS])[0])
            timeout = float(query.get("timeout", [10.0])[0])
        except ValueError:
            raise ValueError(f"{url!r}: cycle_ms must be an integer and timeout a number") from None
        if cycle not in (1, 2, 4, 8, 16, 32, 64, 128, 256, 512):
            raise ValueError(f"{url!r}: cycle_ms must be a power of two from 1 to 512")
        return cls(parts.netloc, station, cycle, timeout)


def gsdml_path() -> Any:
    """pywsg's GSDML (a package resource)."""
    return importlib.resources.files("pywsg.fieldbus.descriptions").joinpath(GSDML_NAME)


SETTLE_FRAMES = 2
"""Input frames a write waits for after the output frame that carried it (:meth:`ProfinetExchange.write_outputs`)."""


class ProfinetExchange:
    """An ``ImageExchange`` over one PROFINET AR: ``read_inputs()`` (12 bytes), ``write_outputs(8 bytes)``."""

    def __init__(self, url: ProfinetUrl, device: Any, cyclic: Any) -> None:
        self.url = url
        self._device = device
        self._cyclic = cyclic

    @classmethod
    async def open(cls, url: str | ProfinetUrl) -> ProfinetExchange:
        """Find the station by DCP, connect an AR built from the GSDML, start cyclic IO."""
        u = url if isinstance(url, ProfinetUrl) else ProfinetUrl.parse(url)
        pn = _profinet()
        return await asyncio.to_thread(cls._connect, u, pn)

    @classmethod
    def _connect(cls, u: ProfinetUrl, pn: Any) -> ProfinetExchange:
        from profinet.gsdml import load_gsdml

        with importlib.resources.as_file(gsdml_path()) as path:
            gsdml = load_gsdml(path)
        # Watchdog and data hold time at least HOLD_MS: a Python controller's sending thread stalls for a
        # few cycles now and then, which must not end the AR (docs/fieldbus.md, "PROFINET")
        factor = max(3, -(-HOLD_MS // u.cycle_ms))
        setup = pn.IOCRSetup(slots=gsdml.build_io_slots(), reduction_ratio=u.cycle_ms, watchdog_factor=factor,
                             data_hold_factor=factor)
        try:
            device = pn.ProfinetDevice.discover(u.station, u.iface, timeout=u.timeout)
        except PermissionError as exc:
            raise FieldbusConnectionError(f"PROFINET on {u.iface} needs root or CAP_NET_RAW: {exc}") from None
        except OSError as exc:
            raise FieldbusConnectionError(f"PROFINET on {u.iface}: {exc.strerror or exc}") from None
        except pn.DCPDeviceNotFoundError:
            raise FieldbusConnectionError(f"no PROFINET station {u.station!r} answers DCP on {u.iface}") from None
        try:
            cyclic = device.start_cyclic(setup)   # its alarm listener acknowledges diagnosis alarms
        except Exception as exc:
            device.close()
            raise FieldbusConnectionError(f"PROFINET connect to {u.station!r} failed: {exc}") from None
        return cls(u, device, cyclic)

    async def read_inputs(self) -> bytes:
        """The 12 input bytes of the device's newest valid frame. Right after connect (the device's IOPS
        still BAD) or while it sends none, wait for one, up to the URL's ``timeout`` s: a zero image
        would read as a gripper that is not IDLE and send the PLC program into its error branch."""
        data = self._cyclic.get_input_data(WSG_SLOT, WSG_SUBSLOT)
        if data is not None:
            return bytes(data)
        deadline = time.monotonic() + self.url.timeout
        while data is None:
            if not self._cyclic.is_running:
                raise FieldbusConnectionError(f"PROFINET AR with {self.url.station!r} lost")
            if time.monotonic() > deadline:
                raise FieldbusConnectionError(f"PROFINET: no valid input data from {self.url.station!r} within "
                                              f"{self.url.timeout:g} s (IOPS BAD)")
            await asyncio.sleep(self.url.cycle_ms / 1000)
            data = self._cyclic.get_input_data(WSG_SLOT, WSG_SUBSLOT)
        return bytes(data)

    async def write_outputs(self, data: bytes) -> None:
        if len(data) != 8:
            raise ValueError(f"the output image is 8 bytes, got {len(data)}")
        stats = self._cyclic.stats
        sent = stats.frames_sent
        self._cyclic.set_output_data(WSG_SLOT, WSG_SUBSLOT, bytes(data))
        # So that a read after a write sees the device's answer to it (a command flag set and reset before
        # the device acted would be lost, or a stale IDLE taken for "done"): wait for the output frame that
        # carries the write, then SETTLE_FRAMES input frames (the device applies outputs and refreshes its
        # inputs on its own cycle); at most the URL's timeout, if the controller's thread stalls.
        deadline = time.monotonic() + self.url.timeout
        await self._until(lambda: stats.frames_sent > sent, deadline)
        received = stats.frames_received
        await self._until(lambda: stats.frames_received >= received + SETTLE_FRAMES, deadline)

    async def _until(self, done: Callable[[], bool], deadline: float) -> None:
        """Poll ``done()`` every quarter cycle until it holds, the AR ends or ``deadline`` (monotonic s) passes."""
        step = self.url.cycle_ms / 4000
        while not done() and self._cyclic.is_running and time.monotonic() < deadline:
            await asyncio.sleep(step)

    async def close(self) -> None:
        def stop() -> None:
            try:
                self._cyclic.stop()
            finally:
                self._device.close()

        await asyncio.to_thread(stop)


async def open_exchange(url: str, *, timeout: float = 3.0) -> ProfinetExchange:
    """``profinet://IFACE/STATION[?cycle_ms=N]``: find, connect, start cyclic IO (``timeout``: DCP, s)."""
    try:
        u = ProfinetUrl.parse(url)
    except ValueError as exc:
        raise FieldbusConnectionError(str(exc)) from None
    if "timeout=" not in url:
        u = ProfinetUrl(u.iface, u.station, u.cycle_ms, max(timeout, 3.0))
    return await ProfinetExchange.open(u)
