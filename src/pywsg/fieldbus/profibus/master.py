"""The PLC side of PROFIBUS DP: the 8/12-byte image exchanged with a WSG by a DP master (pyprofibus).

``profibus://PORT?address=7&baudrate=19200`` — PORT is a serial device (a USB RS-485 adapter) or the
pty ``wsg sim --profibus pty`` prints. Optional query keys: ``master`` (the master's own address,
default 2, the manual's demo PLC) and ``watchdog_ms`` (default 1000; 0 off).

pyprofibus (GPL-2.0+) is the optional extra ``pywsg[profibus]``: it is imported only when an exchange
is opened, and a clear error says how to install it. Its DPM1 runs in a thread of its own (its state
machine is polled). :meth:`ProfibusExchange.read_inputs` waits for the answer to a Data_Exchange that
carried the last written outputs: the exchange watches the requests its PHY sends (outputs and FCB), so
neither a request already on the line with the old outputs nor a repeated request (same FCB, answered
from the slave's stored response, not applied) counts.
"""

from __future__ import annotations

import asyncio
import io
import logging
import threading
import time
from dataclasses import dataclass
from importlib import resources
from typing import Any
from urllib.parse import parse_qs, urlsplit

from ..exchange import FieldbusConnectionError
from ..image import INPUT_SIZE, OUTPUT_SIZE
from .gsd import GSD_NAME

log = logging.getLogger("pywsg.fieldbus.profibus")

SCHEME = "profibus"
INSTALL_HINT = "profibus:// needs pyprofibus (GPL-2.0+, not in the core install): pip install 'pywsg[profibus]'"


class ProfibusError(FieldbusConnectionError):
    """The DP master could not start, or lost its slave."""


@dataclass(frozen=True)
class ProfibusUrl:
    """``profibus://PORT?address=7&baudrate=19200[&master=2&watchdog_ms=1000]``."""

    port: str
    address: int = 7
    baudrate: int = 19200
    master: int = 2
    watchdog_ms: int = 1000

    @classmethod
    def parse(cls, url: str) -> ProfibusUrl:
        parts = urlsplit(url)
        if parts.scheme != SCHEME:
            raise ValueError(f"{url}: not a profibus:// URL")
        port = (parts.netloc + parts.path) if parts.netloc else parts.path
        if not port:
            raise ValueError(f"{url}: no serial port (profibus:///dev/ttyUSB0?address=7&baudrate=19200)")
        query = {k: v[-1] for k, v in parse_qs(parts.query).items()}
        unknown = set(query) - {"address", "baudrate", "master", "watchdog_ms"}
        if unknown:
            raise ValueError(f"{url}: unknown {', '.join(sorted(unknown))} (address, baudrate, master, watchdog_ms)")
        try:
            values = {k: int(v) for k, v in query.items()}
        except ValueError:
            raise ValueError(f"{url}: address, baudrate, master and watchdog_ms are integers") from None
        u = cls(port, **values)
        if not 0 <= u.address <= 125 or not 0 <= u.master <= 125 or u.master == u.address:
            raise ValueError(f"{url}: address and master are different station addresses 0..125")
        if not 0 <= u.watchdog_ms <= 255 * 255 * 10:
            raise ValueError(f"{url}: watchdog_ms 0..650250")
        return u

    def __str__(self) -> str:
        return f"profibus://{self.port}?address={self.address}&baudrate={self.baudrate}"


def offline_note(url: str) -> str:
    """What happens to the slave when this master goes offline (stops polling, as a DP master leaving
    Operate for Offline does): its watchdog expires and the gripper goes fail-safe."""
    u = ProfibusUrl.parse(url)
    if not u.watchdog_ms:
        return (f"PROFIBUS master offline: slave {u.address} has no watchdog (watchdog_ms=0), "
                "it keeps the last outputs")
    return (f"PROFIBUS master offline: slave {u.address}'s watchdog puts the gripper in fail-safe after "
            f"{u.watchdog_ms} ms (FAST STOP, outputs zero); the next master acknowledges it with STOP/ACK")


_pb_log = logging.getLogger("pywsg.fieldbus.profibus.pyprofibus")


def _log_print(*args: Any, **kwargs: Any) -> None:
    """pyprofibus reports with print() on stdout; that would break ``--json`` output: log it instead."""
    text = " ".join(str(a) for a in args).strip()
    if "ERROR" in text or "Warning" in text:
        _pb_log.warning(text)
    elif text:
        _pb_log.debug(text)


def _import_pyprofibus() -> Any:
    try:
        import pyprofibus
        import pyprofibus.dp_master
        import pyprofibus.phy
        import pyprofibus.phy_serial
    except ImportError:
        raise ProfibusError(INSTALL_HINT) from None
    # A module global named print shadows the builtin for that module's own calls only.
    for module in (pyprofibus.phy, pyprofibus.phy_serial, pyprofibus.dp_master):
        module.print = _log_print
    return pyprofibus


def _tracking_phy(pb: Any, port: str, baudrate: int) -> Any:
    """pyprofibus's serial PHY, telling ``phy.on_send(bytes)`` each telegram it puts on the line."""

    class TrackingPhy(pb.phy_serial.CpPhySerial):  # type: ignore[misc]
        __slots__ = ("on_send",)

        def sendData(self, telegramData: Any, srd: Any) -> None:   # pyprofibus's method and names
            self.on_send(bytes(telegramData))
            super().sendData(telegramData, srd)

    phy = TrackingPhy(port=port)
    phy.on_send = lambda data: None
    phy.setConfig(baudrate=baudrate)
    return phy


class ProfibusExchange:
    """An ``ImageExchange`` over PROFIBUS DP: pyprofibus's DPM1 driving one WSG slave."""

    def __init__(self, url: ProfibusUrl, master: Any, desc: Any) -> None:
        self.url = url
        self._master = master
        self._desc = desc
        self._lock = threading.Lock()
        self._outputs = bytes(OUTPUT_SIZE)
        self._inputs: bytes | None = None
        self._cycles = 0           # Data_Exchange responses received
        self._seq = 0              # writes so far
        self._inflight = 0         # the write whose outputs the last new (not repeated) request carried
        self._applied = -1         # the write the last response answered
        self._last_fcb: int | None = None
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name=f"profibus-{url.port}", daemon=True)
        self.error: str | None = None

    @classmethod
    async def open(cls, url: str | ProfibusUrl, timeout: float = 5.0) -> ProfibusExchange:
        """Start the master on the URL's port; return once the slave is in Data_Exch.

        Raises :class:`ProfibusError` when pyprofibus is missing, the port cannot be opened, or no
        slave reaches Data_Exch within ``timeout`` s (wrong address, Ident, baud rate, or no slave).
        """
        u = url if isinstance(url, ProfibusUrl) else ProfibusUrl.parse(url)
        pb = _import_pyprofibus()
        gsd = resources.files("pywsg.fieldbus") / "descriptions" / GSD_NAME
        conf_text = (f"[PHY]\ntype = serial\ndev = {u.port}\nbaud = {u.baudrate}\n"
                     f"[DP]\nmaster_class = 1\nmaster_addr = {u.master}\n"
                     f"[SLAVE_0]\nname = wsg\naddr = {u.address}\ngsd = {gsd}\n"
                     f"input_size = {OUTPUT_SIZE}\noutput_size = {INPUT_SIZE}\nwatchdog_ms = {u.watchdog_ms}\n")
        try:
            conf = pb.PbConf(io.StringIO(conf_text))
            phy = _tracking_phy(pb, u.port, u.baudrate)
            master = conf.makeDPM(phy=phy)
        except pb.ProfibusError as exc:
            raise ProfibusError(f"{u}: {' '.join(str(exc).split())}") from None   # one line
        desc = conf.slaveConfs[0].makeDpSlaveDesc()
        master.addSlave(desc)
        master.initialize()
        self = cls(u, master, desc)
        phy.on_send = self._on_send
        self._thread.start()
        deadline = time.monotonic() + timeout
        while self._inputs is None:
            if time.monotonic() > deadline or self.error:
                await self.close()
                raise ProfibusError(self.error or f"{u}: no DP slave reached Data_Exch within {timeout:g} s "
                                    f"(station address, baud rate, Ident 5555h?)")
            await asyncio.sleep(0.002)
        return self

    def _run(self) -> None:
        master, desc = self._master, self._desc
        try:
            while not self._stop.is_set():
                with self._lock:
                    out = self._outputs
                desc.setMasterOutData(bytearray(out))
                master.run()
                data = desc.getMasterInData()
                if data is not None:
                    with self._lock:
                        self._inputs = bytes(data)
                        self._cycles += 1
                        self._applied = self._inflight
                else:
                    time.sleep(0.0002)   # pyprofibus polls; a short nap keeps it off a whole core
        except Exception as exc:  # the PHY failed (port gone): reported by the next read
            self.error = f"{self.url}: {exc}"
            log.warning("PROFIBUS master stopped: %s", self.error)

    def _on_send(self, data: bytes) -> None:
        """A telegram going out (DPM thread): note which write a Data_Exchange request carries."""
        if len(data) != 14 or data[0] != 0xA2 or data[1] != self.url.address or not data[3] & 0x40:
            return                                     # not an SD3 Data_Exchange request to our slave
        fc = data[3]
        repeat = bool(fc & 0x10) and (fc & 0x20) == self._last_fcb
        self._last_fcb = fc & 0x20
        if not repeat:                                 # a repeat is answered from the stored response
            with self._lock:
                self._inflight = self._seq if data[4:12] == self._outputs else self._seq - 1

    @property
    def read_timeout(self) -> float:
        """Seconds :meth:`read_inputs` waits by default: twice the slave's watchdog, at least 3 s. A slow
        moment of the master (pyprofibus retries a telegram after its own short timeout) is not a lost
        slave; one silent for that long has gone fail-safe by its watchdog anyway."""
        return max(3.0, 2 * self.url.watchdog_ms / 1000)

    @property
    def cycles(self) -> int:
        """Data_Exchange cycles completed."""
        return self._cycles

    async def write_outputs(self, data: bytes) -> None:
        """The 8 output bytes for the next Data_Exchange."""
        if len(data) != OUTPUT_SIZE:
            raise ValueError(f"outputs are {OUTPUT_SIZE} bytes")
        with self._lock:
            self._outputs = bytes(data)
            self._seq += 1

    async def read_inputs(self, timeout: float | None = None) -> bytes:
        """The 12 input bytes answering a Data_Exchange that carried the last written outputs.

        ``timeout`` (s; None: :attr:`read_timeout`) bounds the wait before the slave counts as lost."""
        if timeout is None:
            timeout = self.read_timeout
        deadline = time.monotonic() + timeout
        with self._lock:
            want = self._seq
        while True:
            with self._lock:
                if self._applied >= want and self._inputs is not None:
                    return self._inputs
            if self.error:
                raise ProfibusError(self.error)
            if time.monotonic() > deadline:
                raise ProfibusError(f"{self.url}: no Data_Exchange within {timeout:g} s (slave lost?)")
            await asyncio.sleep(0.0005)

    async def close(self) -> None:
        """Go offline as a DP master does: stop polling and close the port. The slave's watchdog
        (``watchdog_ms``) then expires and the gripper goes fail-safe (:func:`offline_note`)."""
        self._stop.set()
        if self._thread.is_alive():
            await asyncio.to_thread(self._thread.join, 2.0)
        self._master.destroy()
