"""The device end of a serial line: a pseudo-terminal (``pty``) or an existing serial device.

Shared by the serial command interface (:mod:`pywsg.server.serial_port`) and the PROFIBUS DP slave
(:mod:`pywsg.fieldbus.profibus.line`). With ``pty`` the line is ``os.openpty()`` in raw mode, and our
own handle on the client side stays open, so a client closing and reopening the port (pyserial
``Serial(path)``) never turns the device side into ``EIO``; :attr:`SerialLine.path` is what the client
opens. A device path is opened through pyserial, which configures the baud rate and framing.
"""

from __future__ import annotations

import os
import tty
from dataclasses import dataclass
from typing import Any


@dataclass
class SerialLine:
    """An open line (or, with the defaults, none): ``fd`` is non-blocking, for the event loop."""

    fd: int = -1
    path: str = ""
    keep_fd: int = -1  # pty: our handle on the client side
    serial: Any = None  # pyserial object for a real device

    def close(self) -> None:
        """Close the line (idempotent)."""
        if self.serial is not None:
            self.serial.close()
        elif self.fd >= 0:
            os.close(self.fd)
        if self.keep_fd >= 0:
            os.close(self.keep_fd)
        self.fd = self.keep_fd = -1


def open_line(port: str, baudrate: int, **serial_options: Any) -> SerialLine:
    """Open ``port`` (``"pty"`` or a device path) at ``baudrate`` bit/s; ``serial_options`` go to
    ``serial.Serial`` (bytesize, parity, stopbits; pyserial's defaults are 8N1) for a device."""
    if port == "pty":
        master, slave = os.openpty()
        tty.setraw(slave)  # no echo, no line editing: the client sees bytes as sent
        line = SerialLine(master, os.ttyname(slave), keep_fd=slave)
    else:
        import serial  # pyserial: configures baud rate and framing on a real port

        port_ = serial.Serial(port, baudrate, timeout=0, **serial_options)
        line = SerialLine(port_.fileno(), port, serial=port_)
    os.set_blocking(line.fd, False)
    return line
