"""Serial command interface: a pseudo-terminal (``pty``) or an existing serial device.

With ``pty`` the server opens ``os.openpty()``, puts the line in raw mode and keeps its own handle on
the client side open, so a client closing and reopening the port (pyserial ``Serial(path)``) never
turns the device side into ``EIO``; :attr:`SerialServer.path` is what the client opens. With a device
path the port is opened through pyserial at ``baudrate`` (8N1, no flow control).

The serial line has one device session. Output the client does not read is kept up to the soft limit;
above it auto-update packets are dropped, and above the hard limit the oldest output is discarded
(a serial line cannot be "closed" on a client that stopped reading) - whole frames only: output
partly written is finished first, so the reader never sees a torn frame.
"""

from __future__ import annotations

import asyncio
import errno
import logging
import os
from collections import deque
from typing import Any

from ..protocol import Frame
from .device_api import GripperLike
from .limits import DEFAULT_LIMITS, Limits, droppable
from .netfault import Shaper, net_faults
from .scheduler import DeviceRunner
from .serial_line import SerialLine, open_line
from .trace import log_replies

log = logging.getLogger("pywsg.server.serial")

READ_CHUNK = 4096


class SerialServer:
    """Serves ``gripper`` on a pty (``port="pty"``) or a serial device path."""

    def __init__(
        self,
        gripper: GripperLike,
        runner: DeviceRunner,
        port: str = "pty",
        baudrate: int = 115200,
        limits: Limits = DEFAULT_LIMITS,
    ) -> None:
        self.gripper = gripper
        self.runner = runner
        self.requested = port
        self.baudrate = baudrate
        self.limits = limits
        self.path = ""
        self.session: Any = None
        self.dropped = 0
        self._line = SerialLine()
        self._fd = -1  # the line's, read on every byte
        self._out: deque[bytes] = deque()
        self._out_size = 0
        self._head_sent = 0  # bytes of the first queued entry already written
        self._writing = False
        self._loop: asyncio.AbstractEventLoop | None = None
        self.net = net_faults(gripper)
        """Network faults (garbled bytes, latency, bandwidth, silence; :mod:`pywsg.server.netfault`)."""
        self.shaper = Shaper(self.net, lambda data: self._send([data]))

    async def start(self) -> SerialServer:
        self._loop = asyncio.get_running_loop()
        self._line = open_line(self.requested, self.baudrate)
        self._fd, self.path = self._line.fd, self._line.path
        self.session = self.gripper.open_session("serial", peer=self.path, deliver=self.deliver)
        self._loop.add_reader(self._fd, self._on_readable)
        return self

    @property
    def address(self) -> str:
        return f"serial://{self.path}?baudrate={self.baudrate}"

    def _on_readable(self) -> None:
        try:
            data = os.read(self._fd, READ_CHUNK)
        except BlockingIOError:
            return
        except OSError as exc:
            if exc.errno == errno.EIO:  # no client side open (only without our keep-open handle)
                return
            raise
        if not data:
            return
        net = self.net
        if net.active:
            if net.swallow(data):
                return  # a silent gripper
            data = net.garble_bytes(data)  # noise on the line
        replies = self.gripper.feed(self.session, data)
        if replies:
            if log.isEnabledFor(logging.INFO):
                log_replies(log, f"serial {self.path}", replies)
            if net.active or self.shaper.busy:
                for f in replies:
                    self.shaper.send(f.encode())
                return
            self._send([f.encode() for f in replies])

    def deliver(self, frame: Frame) -> None:
        if droppable(frame.command_id) and self._out_size > self.limits.output_soft:
            self.dropped += 1
            return
        if self.net.active or self.shaper.busy:
            self.shaper.send(frame.encode())
            return
        self._send([frame.encode()])

    @property
    def buffered(self) -> int:
        return self._out_size

    def _send(self, frames: list[bytes]) -> None:
        """Write whole frames, queueing what the line does not take now. Above the hard limit
        queued frames are discarded, oldest first, but never the one partly written: the reader
        must not see a torn frame."""
        if self._fd < 0:
            return
        out = self._out
        if not out:
            data = frames[0] if len(frames) == 1 else b"".join(frames)
            try:
                n = os.write(self._fd, data)
            except BlockingIOError:
                n = 0
            except OSError as exc:
                log.debug("serial %s: write failed: %s", self.path, exc)
                return
            if n == len(data):
                return
            while n >= len(frames[0]):  # frames written whole
                n -= len(frames[0])
                frames = frames[1:]
            self._head_sent = n
            self._out_size -= n
        for f in frames:
            out.append(f)
            self._out_size += len(f)
        while self._out_size > self.limits.output_hard:
            i = 1 if self._head_sent else 0  # the head is on the wire already: finish it
            if i >= len(out):
                break
            self._out_size -= len(out[i])
            del out[i]
            self.dropped += 1
        if not self._writing and self._loop is not None:
            self._writing = True
            self._loop.add_writer(self._fd, self._on_writable)

    def _on_writable(self) -> None:
        out = self._out
        while out:
            chunk = out[0]
            sent = self._head_sent
            try:
                n = os.write(self._fd, memoryview(chunk)[sent:])
            except BlockingIOError:
                return
            except OSError:
                out.clear()
                self._out_size = 0
                self._head_sent = 0
                break
            self._out_size -= n
            if sent + n < len(chunk):
                self._head_sent = sent + n
                return
            self._head_sent = 0
            out.popleft()
        self._writing = False
        if self._loop is not None:
            self._loop.remove_writer(self._fd)

    async def close(self) -> None:
        self.shaper.close()
        if self._loop is not None and self._fd >= 0:
            self._loop.remove_reader(self._fd)
            if self._writing:
                self._loop.remove_writer(self._fd)
        if self.session is not None:
            self.gripper.close_session(self.session)
            self.session = None
        self._line.close()
        self._fd = -1
