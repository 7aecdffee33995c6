"""The DP slave on a serial line: a new pty (tests, a master in the same machine) or a real port
(a USB RS-485 adapter), on the asyncio loop of the virtual gripper.

Bytes in → :class:`~.fdl.FdlParser` → :class:`~.dp.DpSlave` → the response. The line's timing, as a
DP slave keeps it (IEC 61158-4-3):

- **Framing by idle time.** Each read is stamped; a gap between two reads longer than T_SYN (33 bit
  times) plus the time the new bytes took on the wire plus :data:`RX_SLACK_S` means the line was
  idle: a telegram begun before it is dropped as cut off, and after a line error the receiver waits
  for such a gap before it reads a telegram again. A pty has no bit timing: there the gap is all
  there is.
- **Station delay.** An answer starts no earlier than the master's min TSDR (Set_Prm, in bit times)
  after the read that completed its request, on any event loop: uvloop rounds timers to whole
  milliseconds, so the last 2 ms are waited busily (never early; a sleep would wake up late on a
  loaded CPU). The standard's min TSDR is 11..255 bit times: at 19.2 kbit/s and above that wait is
  under 1.2 ms per answer. On a real port an answer that could not start within the GSD's MaxTsdr
  for the rate is not sent at all (counted in :attr:`ProfibusAdapter.late_responses`): the master
  has given up on it and repeats the request, and a late answer would only collide with that. On a
  pty (one master, no bus) it is still sent.
- **Watchdog.** One timer, re-armed whenever the slave's deadline moves earlier (a Set_Prm that
  shrinks it); expiry is also judged when a telegram arrives (:meth:`~.dp.DpSlave.handle`).
- **Baud rate.** A fixed rate, or (``baudrate=None``, a real port only) detection: the slave listens
  at each declared rate in turn and locks to the one at which it reads a telegram (:mod:`.baud`).

With a pty the slave keeps its own handle on the client side open, so a master closing and reopening
the port never turns the line into ``EIO``. A real port is opened 8E1 (PROFIBUS's UART character:
8 data bits, even parity, 1 stop bit) with input parity checking on and characters with a parity
error dropped (``INPCK | IGNPAR``; pyserial turns checking off), so the telegram they belong to fails
its length or FCS and gets no answer. A pty has no parity: its kernel driver clears the parity bit
whatever is asked (CS8, no parity), so parity cannot be checked there.
"""

from __future__ import annotations

import asyncio
import errno
import logging
import os
import termios
import time
from collections.abc import Callable

from ...server.serial_line import SerialLine, open_line
from . import fdl
from .baud import BaudSearch
from .dp import BUS_NAME, DpSlave, DpState, ImagePort
from .gsd import facts

log = logging.getLogger("pywsg.fieldbus.profibus")

READ_CHUNK = 4096
DEFAULT_BAUDRATE = 19200
#: Scheduling slack (s) added to T_SYN before a gap between reads counts as an idle line: a process
#: does not see sub-millisecond gaps (the kernel, a USB adapter's latency timer and a busy CPU all
#: delay a read by up to about that much).
RX_SLACK_S = 0.001
#: Below this many seconds an answer's delay is waited busily, not with an event-loop timer.
PRECISE_WAIT_S = 0.002

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


def check_baudrate(baudrate: int | None) -> None:
    """ValueError unless the GSD declares ``baudrate`` (None: detection, always allowed here)."""
    rates = facts().baud_rates
    if baudrate is not None and baudrate not in rates:
        raise ValueError(f"PROFIBUS baud rate {baudrate} is not one WEIS5555.gsd declares "
                         f"({', '.join(str(r) for r in rates)}, or auto)")


def _check_parity(fd: int) -> None:
    """Turn input parity checking on and drop characters with a parity error (pyserial clears INPCK)."""
    attrs = termios.tcgetattr(fd)
    attrs[0] = (attrs[0] | termios.INPCK | termios.IGNPAR) & ~termios.PARMRK
    termios.tcsetattr(fd, termios.TCSANOW, attrs)


class ProfibusAdapter:
    """The WSG's PROFIBUS DP interface: one :class:`DpSlave` on ``port`` (``"pty"`` or a device path).

    ``controller`` is the gripper's FieldbusController (the same one Modbus/TCP uses).
    ``baudrate`` in bit/s, one the GSD declares; None: detect it (a real port only).
    ``on_address_change(address, locked)`` is called after a Set_Slave_Address (persist both).
    ``baud_dwell_s``: seconds at each rate while detecting.
    """

    name = BUS_NAME

    def __init__(self, controller: ImagePort, port: str = "pty", address: int = 7,
                 baudrate: int | None = DEFAULT_BAUDRATE,
                 on_address_change: Callable[[int, bool], None] | None = None, *,
                 address_locked: bool = False, baud_dwell_s: float | None = None) -> None:
        check_baudrate(baudrate)
        if baudrate is None and port == "pty":
            raise ValueError("baud-rate detection needs a serial port: a pty has no bit timing "
                             "(give a rate the GSD declares)")
        self.controller = controller
        self.requested = port
        self.auto_baud = baudrate is None
        self.baudrate = baudrate or max(facts().baud_rates)
        self._dwell = baud_dwell_s
        self.search: BaudSearch | None = None
        self.slave = DpSlave(controller, address, on_address_change, address_locked)
        self.parser = fdl.FdlParser()
        self.path = ""
        self.line_errors = 0
        self.dropped_responses = 0
        self.late_responses = 0    # answers not sent: they could not start within MaxTsdr
        self.failure: str | None = None   # why the port stopped working
        self._line = SerialLine()
        self._fd = -1  # the line's, read on every byte
        self._loop: asyncio.AbstractEventLoop | None = None
        self._timer: asyncio.TimerHandle | None = None
        self._timer_due: float | None = None
        self._baud_timer: asyncio.TimerHandle | None = None
        self._last_rx = float("-inf")
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
        if self.auto_baud:
            now = time.monotonic()
            kw = {} if self._dwell is None else {"dwell_s": self._dwell}
            self.search = BaudSearch(facts().baud_rates, now, **kw)
            self._set_rate(self.search.rate)
            self._baud_timer = self._loop.call_later(self.search.dwell_s / 2, self._on_baud_timer)
        log.info("PROFIBUS DP slave %d on %s at %s", self.slave.address, self.path,
                 "an automatically detected rate" if self.auto_baud else f"{self.baudrate} bit/s")
        return self

    @property
    def address(self) -> int:
        """The station address now (Set_Slave_Address may change it)."""
        return self.slave.address

    @property
    def url(self) -> str:
        """What a master opens: ``profibus://PATH?address=7&baudrate=19200`` (no rate when detected)."""
        rate = "" if self.auto_baud else f"&baudrate={self.baudrate}"
        return f"profibus://{self.path}?address={self.slave.address}{rate}"

    @property
    def idle_s(self) -> float:
        """Seconds of silence between reads that count as an idle line (T_SYN + slack)."""
        return fdl.TSYN_BITS / self.baudrate + RX_SLACK_S

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
        if self.search is not None:
            rate = (f"{bitrate_text(self.baudrate)} (automatically detected)" if self.search.locked
                    else "searching (automatic detection)")
        else:
            rate = bitrate_text(self.baudrate) + (" (pty: nominal)" if self.requested == "pty" else "")
        return {"Station Address": str(self.slave.address), "Bitrate": rate, "Interface state": state}

    # --- receiving ---------------------------------------------------------------------------
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
        now = time.monotonic()
        if not data:
            if self._line.serial is not None:
                self._lost(OSError("end of file"))
            return
        # Idle before this read: the gap, less the time these bytes took on the wire, exceeds T_SYN.
        idle = now - self._last_rx - len(data) * fdl.CHAR_BITS / self.baudrate >= self.idle_s
        self._last_rx = now
        slave = self.slave
        for ev in self.parser.feed(data, idle=idle):
            if isinstance(ev, fdl.LineError):
                self.line_errors += 1
                if log.isEnabledFor(logging.DEBUG):
                    log.debug("PROFIBUS %s: %s, %d bytes dropped", self.path, ev.reason, ev.skipped)
                continue
            if self.search is not None:
                self.search.heard(now)
            min_tsdr = slave.min_tsdr          # the one in force when the request came (not a new Set_Prm's)
            response = slave.handle(ev, now)
            if response is not None:
                self._answer(response, now, min_tsdr)
        self._arm_watchdog()

    # --- answering ---------------------------------------------------------------------------
    def _answer(self, response: bytes, received: float, min_tsdr: int) -> None:
        """Send ``response`` no earlier than ``min_tsdr`` and no later than MaxTsdr (bit times) after
        ``received``. A master that sets min TSDR near or above MaxTsdr gets its min TSDR, with the
        GSD's window beyond the standard's smallest min TSDR (11 bit times) still allowed after it."""
        rate = self.baudrate
        max_tsdr = facts().max_tsdr.get(rate, 0xFFFF)
        due = received + min_tsdr / rate
        self._send_at(response, due, max(received + max_tsdr / rate, due + (max_tsdr - 11) / rate))

    def _send_at(self, response: bytes, due: float, latest: float) -> None:
        remaining = due - time.monotonic()
        if remaining > PRECISE_WAIT_S:
            # An event-loop timer for the bulk (uvloop's fire up to 1 ms early), then this again.
            assert self._loop is not None
            self._loop.call_later(remaining - PRECISE_WAIT_S / 2, self._send_at, response, due, latest)
            return
        while time.monotonic() < due:
            pass   # the last ≤ 2 ms: a busy wait, as a sleep's wake-up comes ms late on a loaded CPU
        if time.monotonic() > latest and self._line.serial is not None:
            # On a line the master has given up on it and repeats: a late answer would collide with
            # that. A pty has one master and no bus: there it is still sent.
            self.late_responses += 1
            log.debug("PROFIBUS %s: answer %.1f ms after MaxTsdr dropped", self.path,
                      1000 * (time.monotonic() - latest))
            return
        self._respond(response)

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

    # --- watchdog ----------------------------------------------------------------------------
    def _arm_watchdog(self) -> None:
        """One timer at the slave's deadline; moved when the deadline moved earlier (a Set_Prm that
        shrank the watchdog), cancelled when there is none."""
        deadline = self.slave.watchdog_deadline
        if self._loop is None or self._closed:
            return
        if deadline is None:
            if self._timer is not None:
                self._timer.cancel()
                self._timer = self._timer_due = None
            return
        if self._timer is not None and self._timer_due is not None and self._timer_due <= deadline:
            return                      # fires no later than needed; it re-arms itself if early
        if self._timer is not None:
            self._timer.cancel()
        self._timer_due = deadline
        self._timer = self._loop.call_later(max(0.0, deadline - time.monotonic()), self._on_watchdog)

    def _on_watchdog(self) -> None:
        self._timer = self._timer_due = None
        if self._closed:
            return
        self.slave.check_watchdog(time.monotonic())
        self._arm_watchdog()

    # --- baud rate ---------------------------------------------------------------------------
    def _on_baud_timer(self) -> None:
        if self._closed or self.search is None or self._loop is None:
            return
        rate = self.search.tick(time.monotonic(), self.slave.watchdog_s)
        if rate is not None and rate != self.baudrate:
            self._set_rate(rate)
        self._baud_timer = self._loop.call_later(self.search.dwell_s / 2, self._on_baud_timer)

    def _set_rate(self, rate: int) -> None:
        """Listen at ``rate`` from now on (pyserial rewrites the termios: parity checking again), and
        drop what the port received at the rate before."""
        try:
            if self._line.serial is not None and self._line.serial.baudrate != rate:
                self._line.serial.baudrate = rate
                _check_parity(self._fd)
                termios.tcflush(self._fd, termios.TCIFLUSH)
        except (OSError, ValueError) as exc:
            log.warning("PROFIBUS %s: cannot set %d bit/s: %s", self.path, rate, exc)
            return
        self.baudrate = rate
        self.parser.reset()
        log.debug("PROFIBUS %s: listening at %d bit/s", self.path, rate)

    def _lost(self, exc: OSError) -> None:
        """The port failed (a USB adapter unplugged): stop reading it, once, and say so."""
        if self.failure is None:
            self.failure = f"{self.path}: {exc.strerror or exc}"
            log.error("PROFIBUS line lost: %s", self.failure)
        if self._loop is not None and self._fd >= 0:
            self._loop.remove_reader(self._fd)

    async def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        detach = getattr(self.controller, "detach_bus", None)
        if detach is not None:
            detach(self)
        for timer in (self._timer, self._baud_timer):
            if timer is not None:
                timer.cancel()
        self._timer = self._baud_timer = None
        if self._loop is not None and self._fd >= 0:
            self._loop.remove_reader(self._fd)
        self._line.close()
        self._fd = -1
