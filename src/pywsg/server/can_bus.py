"""CAN command interface — **inferred**: the WSG manuals name CAN (000 §1.1) but do not specify a mapping.

Design (as a public ROS driver, TRI's ``schunk_wsg_driver`` ``WSGCANInterface``, does it): the
ordinary binary protocol byte stream is cut into CAN data frames of up to 8 bytes, all but the last
full. Requests arrive on ``rx_id`` (default 01h), replies and auto-updates leave on ``tx_id``
(default 02h = ``rx_id`` + 1 in that driver), standard 11-bit IDs. The device parser reassembles
frames across CAN frames exactly as on a serial line (length from the header, CRC checked); a lost
or reordered fragment fails the CRC (answered E_CHECKSUM_ERROR like any corrupt frame) and the
parser resynchronises on the next preamble. Other identifiers, remote and error frames are ignored
(acceptance filter on the bus, checked again per frame), and so are CAN FD frames and any frame over
8 data bytes: the mapping is classic CAN. The driver side is
:mod:`pywsg.client.can`. Needs python-can (``pywsg[can]``); tests use its ``virtual``
interface.

Cost per frame (issue 23 item 15, issue 33 item 13): the reader thread only queues the frames it
reads; the loop takes every frame that is ready in one turn (up to :data:`DRAIN`), feeds their bytes to
the gripper at once and sends the answers of that turn as one byte stream, cut into full CAN frames
(a 10-byte E_CHECKSUM_ERROR reply then takes 1.25 CAN frames instead of 2). On the ``virtual`` bus,
python-can's per-message ``send`` and ``recv`` are replaced by batches (:mod:`.can_virtual`); on other
interfaces the CAN frames of the stream are made once per distinct 8 bytes (:data:`MSG_CACHE`) and
sent with python-can's ``send``, read by its ``Notifier``. See docs/benchmarks.md.
"""

from __future__ import annotations

import asyncio
import collections
import functools
import logging
from collections.abc import Iterable
from typing import Any

from ..protocol import Frame
from . import can_virtual
from .device_api import GripperLike
from .netfault import Shaper, net_faults
from .scheduler import DeviceRunner

log = logging.getLogger("pywsg.server.can")

DRAIN = 512
"""CAN frames (≤ 4 KiB) fed to the gripper per loop turn at most, like TCP's read slice: a flood
leaves the other clients their turn."""
MSG_CACHE = 1024
"""Distinct 8-byte pieces of reply whose CAN frames are kept (a flood of bad frames gets the same reply
each time, so the stream of replies repeats)."""


@functools.cache
def reply_message_class(can: Any) -> Any:
    """A ``can.Message`` subclass for the sim's replies: same fields, but its deep copy (what
    python-can's ``virtual`` bus makes of every message it sends, per receiver) copies the fields
    directly into a plain ``can.Message`` instead of going through :func:`copy.deepcopy` for the
    data and the channel: 1.6 µs instead of 4.7 µs a copy. The sim never changes a message it sent."""

    class ReplyMessage(can.Message):  # type: ignore[misc]
        __slots__ = ()

        def __deepcopy__(self, memo: Any) -> Any:
            return can.Message(
                timestamp=self.timestamp, arbitration_id=self.arbitration_id,
                is_extended_id=self.is_extended_id, is_remote_frame=self.is_remote_frame,
                is_error_frame=self.is_error_frame, channel=self.channel, dlc=self.dlc,
                data=bytearray(self.data), is_fd=self.is_fd, is_rx=self.is_rx,
                bitrate_switch=self.bitrate_switch, error_state_indicator=self.error_state_indicator)

    return ReplyMessage


class CanServer:
    """Serves ``gripper`` on a python-can bus (``interface``/``channel``)."""

    def __init__(
        self,
        gripper: GripperLike,
        runner: DeviceRunner,
        channel: str,
        interface: str = "virtual",
        rx_id: int = 0x01,
        tx_id: int = 0x02,
        bitrate: int = 500_000,
    ) -> None:
        self.gripper = gripper
        self.runner = runner
        self.channel = channel
        self.interface = interface
        self.rx_id = rx_id
        self.tx_id = tx_id
        self.bitrate = bitrate
        self.foreign = 0  # CAN frames ignored: another identifier, remote or error frames
        self.session: Any = None
        self._bus: Any = None
        self._notifier: Any = None
        self._can: Any = None  # the python-can module, once started
        self._message: Any = None  # its Message class for our replies (reply_message_class)
        self._loop: asyncio.AbstractEventLoop | None = None
        self._inbox: collections.deque[bytearray] = collections.deque()  # data of accepted frames, in order
        self._draining = False  # a _drain is scheduled on the loop
        self._msgs: dict[bytes, Any] = {}  # up to 8 bytes of reply -> its CAN frame
        self._virtual = False  # python-can's virtual bus, sent to and read in batches
        self.net = net_faults(gripper)
        """Network faults (drop, reorder, garble, latency, silence) on each CAN frame (:mod:`pywsg.server.netfault`)."""
        self.shaper = Shaper(self.net, self._send_frame, ordered=False)

    async def start(self) -> CanServer:
        try:
            import can
        except ImportError as exc:  # optional extra
            raise RuntimeError("CAN needs python-can: pip install 'pywsg[can]'") from exc
        self._can = can
        self._message = reply_message_class(can)
        self._loop = asyncio.get_running_loop()
        kwargs: dict[str, Any] = {"interface": self.interface, "channel": self.channel,
                                  "can_filters": [{"can_id": self.rx_id, "can_mask": 0x7FF, "extended": False}]}
        if self.interface != "virtual":
            kwargs["bitrate"] = self.bitrate
        self._bus = can.Bus(**kwargs)
        self.session = self.gripper.open_session("can", peer=self.channel, deliver=self.deliver)
        self._virtual = can_virtual.batchable(self._bus)
        if self._virtual:
            self._notifier = can_virtual.Reader(self._bus, self._on_messages, name=f"can-reader-{self.channel}")
        else:  # no loop given: the Notifier's thread calls _on_message, which only queues (see _drain)
            self._notifier = can.Notifier(self._bus, [self._on_message])
        return self

    @property
    def address(self) -> str:
        """The URL a client connects with (its ``request_id`` is our ``rx_id``), e.g. for ``wsg --url``."""
        rate = "" if self.interface == "virtual" else f"&bitrate={self.bitrate}"
        return (f"can://{self.channel}?interface={self.interface}{rate}"
                f"&request_id=0x{self.rx_id:X}&reply_id=0x{self.tx_id:X}")

    def _on_message(self, msg: Any) -> None:
        """On the Notifier's thread: one frame (see :meth:`_on_messages`)."""
        self._on_messages((msg,))

    def _on_messages(self, msgs: Iterable[Any]) -> None:
        """On the reader's thread: queue the accepted frames' data; wake the loop once per batch."""
        rx_id, inbox = self.rx_id, self._inbox
        for msg in msgs:
            if (msg.arbitration_id != rx_id or msg.is_remote_frame or msg.is_error_frame
                    or msg.is_extended_id or msg.is_fd or len(msg.data) > 8):
                self.foreign += 1
                continue
            inbox.append(msg.data)
        if inbox and not self._draining:
            self._draining = True
            try:
                self._loop.call_soon_threadsafe(self._drain)  # type: ignore[union-attr]
            except RuntimeError:  # the loop is closed: the server is gone
                pass

    def _drain(self) -> None:
        """On the loop: up to :data:`DRAIN` queued frames, their bytes fed to the gripper at once
        (one identifier, so one byte stream: the parser reassembles across frames as before)."""
        inbox = self._inbox
        if self.session is None:
            self._draining = False
            inbox.clear()
            return
        if len(inbox) > DRAIN:  # more than a turn's worth: come back after the other clients
            parts = [inbox.popleft() for _ in range(DRAIN)]
            asyncio.get_running_loop().call_soon(self._drain)
        else:
            self._draining = False  # before taking: a frame queued from now on schedules a new turn
            parts = [inbox.popleft() for _ in range(len(inbox))]
        net = self.net
        if net.active:  # the faults act on each CAN frame, as on the bus
            kept: list[bytes] = []
            for part in parts:
                one = bytes(part)
                if net.swallow(one) or net.lose():
                    continue  # a silent gripper, or a CAN frame lost (the request's CRC then fails)
                kept.append(net.garble_bytes(one))
            data = b"".join(kept)
        else:
            data = b"".join(parts)
        if not data:
            return
        replies = self.gripper.feed(self.session, data)
        if replies:  # one byte stream, as on a serial line: the driver's parser reassembles it
            self._send(b"".join([frame.encode() for frame in replies]))

    def deliver(self, frame: Frame) -> None:
        self._send(frame.encode())

    def _messages(self, data: bytes) -> list[Any]:
        """``data`` as CAN frames of up to 8 bytes on ``tx_id`` (all but the last full), each made once
        per distinct 8 bytes: python-can's send does not change a message, so one can go out many times."""
        cache, msgs = self._msgs, []
        for i in range(0, len(data), 8):
            chunk = data[i : i + 8]
            msg = cache.get(chunk)
            if msg is None:
                msg = self._message(arbitration_id=self.tx_id, data=bytearray(chunk), is_extended_id=False)
                if len(cache) >= MSG_CACHE:
                    cache.clear()
                cache[chunk] = msg
            msgs.append(msg)
        return msgs

    def _send(self, data: bytes) -> None:
        bus = self._bus
        if bus is None:
            return
        if self.net.active or self.shaper.busy:
            # network faults act on each CAN frame: one lost or late fragment spoils the reply
            for i in range(0, len(data), 8):
                self.shaper.send(data[i : i + 8])
            return
        try:
            if self._virtual and can_virtual.send_many(
                    bus, self.tx_id, [data[i : i + 8] for i in range(0, len(data), 8)]):
                return
            for msg in self._messages(data):
                bus.send(msg)
        except self._can.CanError as exc:  # the rest of this reply is lost, as on a bus that fails
            log.debug("can %s: send failed: %s", self.channel, exc)

    def _send_frame(self, chunk: bytes) -> bool:
        """One CAN frame (the shaper's path, with network faults)."""
        bus = self._bus
        if bus is None:
            return False
        can = self._can
        try:
            bus.send(self._message(arbitration_id=self.tx_id, data=chunk, is_extended_id=False))
        except can.CanError as exc:
            log.debug("can %s: send failed: %s", self.channel, exc)
            return False
        return True

    async def close(self) -> None:
        self.shaper.close()
        if self._notifier is not None:
            self._notifier.stop()
            self._notifier = None
        self._inbox.clear()
        if self.session is not None:
            self.gripper.close_session(self.session)
            self.session = None
        if self._bus is not None:
            self._bus.shutdown()
            self._bus = None
