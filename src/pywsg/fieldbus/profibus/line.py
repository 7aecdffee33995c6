"""The DP slave on a serial line: a new pty (tests, a master in the same machine) or a real port
(a USB RS-485 adapter), on the asyncio loop of the virtual gripper.

Bytes in → :class:`~.fdl.FdlParser` → :class:`~.dp.DpSlave` → the response written at once (on a
real port not before the master's min TSDR from Set_Prm, so its RS-485 driver has turned round). With
a pty the slave keeps its own handle on the client side open, so a master closing and reopening the
port never turns the line into ``EIO``. A real port is opened 8E1 (PROFIBUS's UART character: 8 data
bits, even parity, 1 stop bit) at the given baud rate, with input parity checking on and characters
with a parity error dropped (``INPCK | IGNPAR``; pyserial turns checking off), so the telegram they
belong to fails its length or FCS and gets no answer. A pty has no parity: its kernel driver clears
the parity bit whatever is asked (CS8, no parity), so parity cannot be checked there.
"""

from __future__ import annotations

import asyncio
import errno
import logging
import os
import termios
from collections.abc import Callable

from ...server.serial_line import SerialLine, open_line
from . import fdl
from .dp import BUS_NAME, DpSlave, DpState, ImagePort
from .gsd import facts

log = logging.getLogger("pywsg.fieldbus.profibus")

READ_CHUNK = 4096
DEFAULT_BAUDRATE = 19200

_STATE_TEXT = {
    DpState.DATA_EXCH: "Online",
    DpState.WAIT_CFG: "Waiting for configuration (Wait_Cfg)",
    DpState.WAIT_PRM: "Waiting for parameters (Wait_Prm)",
}


def bitrate_text(baudrate: int) -> str:
    """A baud rate as the Fieldbus Monitor shows it: ``19.2 kbit/s``, ``1.5 Mbit/s``."""
    if baudrate >= 1_000_000:
        return f"{baudrate / 1_000_000:g} Mbit/s"
    return f"{baudrate / 1000:g} kbit/s"


def check_baudrate(baudrate: int) -> None:
    """ValueError unless the GSD declares ``baudrate`` (the slave answers in time only at those)."""
    rates = facts().baud_rates
    if baudrate not in rates:
        raise ValueError(f"PROFIBUS baud rate {baudrate} is not one WEIS5555.gsd declares "
                         f"({', '.join(str(r) for r in rates)})")


def _check_parity(fd: int) -> None:
    """Turn input parity checking on and drop characters with a parity error (pyserial clears INPCK)."""
    attrs = termios.tcgetattr(fd)
    attrs[0] = (attrs[0] | termios.INPCK | termios.IGNPAR) & ~termios.PARMRK
    termios.tcsetattr(fd, termios.TCSANOW, attrs)


class ProfibusAdapter:
    """The WSG's PROFIBUS DP interface: one :class:`DpSlave` on ``port`` (``"pty"`` or a device path).

    ``controller`` is the gripper's FieldbusController (the same one Modbus/TCP uses).
    ``on_address_change(address)`` is called after a Set_Slave_Address (persist it in the settings).
    """

    name = BUS_NAME

    def __init__(self, controller: ImagePort, port: str = "pty", address: int = 7,
                 baudrate: int = DEFAULT_BAUDRATE,
                 on_address_change: Callable[[int], None] | None = None) -> None:
        check_baudrate(baudrate)
        self.controller = controller
        self.requested = port
        self.baudrate = baudrate
        self.slave = DpSlave(controller, address, on_address_change)
        self.parser = fdl.FdlParser()
        self.path = ""
        self.line_errors = 0
        self.dropped_responses = 0
        self.failure: str | None = None   # why the port stopped working
        self._line = SerialLine()
        self._fd = -1  # the line's, read on every byte
        self._loop: asyncio.AbstractEventLoop | None = None
        self._timer: asyncio.TimerHandle | None = None
        self._closed = False

    async def start(self) -> ProfibusAdapter:
        self._loop = asyncio.get_running_loop()
        if self.requested == "pty":
            self._line = open_line("pty", self.baudrate)
        else:
            import serial

            self._line = open_line(self.requested, self.baudrate, bytesize=serial.EIGHTBITS,
                                   parity=serial.PARITY_EVEN, stopbits=serial.STOPBITS_ONE)
            _check_parity(self._line.fd)
        self._fd, self.path = self._line.fd, self._line.path
        self._loop.add_reader(self._fd, self._on_readable)
        log.info("PROFIBUS DP slave %d on %s at %d bit/s", self.slave.address, self.path, self.baudrate)
        return self

    @property
    def address(self) -> int:
        """The station address now (Set_Slave_Address may change it)."""
        return self.slave.address

    @property
    def url(self) -> str:
        """What a master opens: ``profibus://PATH?address=7&baudrate=19200``."""
        return f"profibus://{self.path}?address={self.slave.address}&baudrate={self.baudrate}"

    def set_address(self, address: int) -> None:
        """Answer at ``address`` from now on (the web page's station address; not persisted here)."""
        self.slave.set_address(address)
        log.info("PROFIBUS DP: station address now %d", address)

    def bus_state(self) -> dict[str, str]:
        """The Fieldbus Monitor's Bus State rows (003 §6)."""
        state = "Offline" if self._closed else _STATE_TEXT[self.slave.state]
        if self.failure and not self._closed:
            state = f"Offline: {self.failure}"
        elif self.slave.state is DpState.WAIT_PRM and self.slave.last_reason and not self._closed:
            state += f": {self.slave.last_reason}"
        rate = bitrate_text(self.baudrate) + (" (pty: nominal)" if self.requested == "pty" else "")
        return {"Station Address": str(self.slave.address), "Bitrate": rate, "Interface state": state}

    def _on_readable(self) -> None:
        try:
            data = os.read(self._fd, READ_CHUNK)
        except BlockingIOError:
            return
        except OSError as exc:
            if exc.errno == errno.EIO and self._line.serial is None:
                return   # pty: no master side open (cannot happen while we keep our handle)
            self._lost(exc)
            return
        if not data:
            if self._line.serial is not None:
                self._lost(OSError("end of file"))
            return
        assert self._loop is not None
        slave = self.slave
        for ev in self.parser.feed(data):
            if isinstance(ev, fdl.LineError):
                self.line_errors += 1
                if log.isEnabledFor(logging.DEBUG):
                    log.debug("PROFIBUS %s: %s, %d bytes dropped", self.path, ev.reason, ev.skipped)
                continue
            response = slave.handle(ev, self._loop.time())
            if response is None:
                continue
            delay = slave.min_tsdr / self.baudrate if self._line.serial is not None else 0.0
            if delay > 0.0002:   # below that, the time to get here has already passed it
                self._loop.call_later(delay, self._respond, response)
            else:
                self._respond(response)
        if slave.watchdog_deadline is not None and self._timer is None:
            self._timer = self._loop.call_at(slave.watchdog_deadline, self._on_watchdog)

    def _lost(self, exc: OSError) -> None:
        """The port failed (a USB adapter unplugged): stop reading it, once, and say so."""
        if self.failure is None:
            self.failure = f"{self.path}: {exc.strerror or exc}"
            log.error("PROFIBUS line lost: %s", self.failure)
        if self._loop is not None and self._fd >= 0:
            self._loop.remove_reader(self._fd)

    def _respond(self, data: bytes) -> None:
        if self._closed:
            return
        self._write(data)
        self.slave.after_response()

    def _write(self, data: bytes) -> None:
        try:
            n = os.write(self._fd, data)
        except (BlockingIOError, OSError) as exc:
            n = 0
            log.debug("PROFIBUS %s: response not sent: %s", self.path, exc)
        if n != len(data):
            # Nobody reads the line: a bus does not queue, the master will repeat its request.
            self.dropped_responses += 1

    def _on_watchdog(self) -> None:
        self._timer = None
        if self._closed or self._loop is None:
            return
        if self.slave.check_watchdog(self._loop.time()):
            log.warning("PROFIBUS DP station %d: watchdog expired (no telegram from master for %.0f ms)",
                        self.slave.address, 1000 * (self.slave.watchdog_s or 0))
        elif self.slave.watchdog_deadline is not None:
            self._timer = self._loop.call_at(self.slave.watchdog_deadline, self._on_watchdog)

    async def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        detach = getattr(self.controller, "detach_bus", None)
        if detach is not None:
            detach(self)
        if self._timer is not None:
            self._timer.cancel()
            self._timer = None
        if self._loop is not None and self._fd >= 0:
            self._loop.remove_reader(self._fd)
        self._line.close()
        self._fd = -1
