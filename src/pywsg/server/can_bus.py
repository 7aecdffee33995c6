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
"""

from __future__ import annotations

import asyncio
import logging
from typing import Any

from ..protocol import Frame
from .device_api import GripperLike
from .netfault import Shaper, net_faults
from .scheduler import DeviceRunner

log = logging.getLogger("pywsg.server.can")


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
        self.net = net_faults(gripper)
        """Network faults (drop, reorder, garble, latency, silence) on each CAN frame (:mod:`pywsg.server.netfault`)."""
        self.shaper = Shaper(self.net, self._send_frame, ordered=False)

    async def start(self) -> CanServer:
        try:
            import can
        except ImportError as exc:  # optional extra
            raise RuntimeError("CAN needs python-can: pip install 'pywsg[can]'") from exc
        loop = asyncio.get_running_loop()
        kwargs: dict[str, Any] = {"interface": self.interface, "channel": self.channel,
                                  "can_filters": [{"can_id": self.rx_id, "can_mask": 0x7FF, "extended": False}]}
        if self.interface != "virtual":
            kwargs["bitrate"] = self.bitrate
        self._bus = can.Bus(**kwargs)
        self.session = self.gripper.open_session("can", peer=self.channel, deliver=self.deliver)
        self._notifier = can.Notifier(self._bus, [self._on_message], loop=loop)
        return self

    @property
    def address(self) -> str:
        """The URL a client connects with (its ``request_id`` is our ``rx_id``), e.g. for ``wsg --url``."""
        rate = "" if self.interface == "virtual" else f"&bitrate={self.bitrate}"
        return (f"can://{self.channel}?interface={self.interface}{rate}"
                f"&request_id=0x{self.rx_id:X}&reply_id=0x{self.tx_id:X}")

    def _on_message(self, msg: Any) -> None:
        if (msg.arbitration_id != self.rx_id or msg.is_remote_frame or msg.is_error_frame
                or msg.is_extended_id or getattr(msg, "is_fd", False) or len(msg.data) > 8):
            self.foreign += 1
            return
        data = bytes(msg.data)
        net = self.net
        if net.active:
            if net.swallow(data) or net.lose():
                return  # a silent gripper, or a CAN frame lost (the request's CRC then fails)
            data = net.garble_bytes(data)
        replies = self.gripper.feed(self.session, data)
        for frame in replies:
            self._send(frame.encode())

    def deliver(self, frame: Frame) -> None:
        self._send(frame.encode())

    def _send(self, data: bytes) -> None:
        if self._bus is None:
            return
        shaped = self.net.active or self.shaper.busy
        for i in range(0, len(data), 8):
            if shaped:  # network faults act on each CAN frame: one lost or late fragment spoils the reply
                self.shaper.send(data[i : i + 8])
            elif not self._send_frame(data[i : i + 8]):
                return

    def _send_frame(self, chunk: bytes) -> bool:
        import can

        bus = self._bus
        if bus is None:
            return False
        try:
            bus.send(can.Message(arbitration_id=self.tx_id, data=chunk, is_extended_id=False))
        except can.CanError as exc:
            log.debug("can %s: send failed: %s", self.channel, exc)
            return False
        return True

    async def close(self) -> None:
        self.shaper.close()
        if self._notifier is not None:
            self._notifier.stop()
            self._notifier = None
        if self.session is not None:
            self.gripper.close_session(self.session)
            self.session = None
        if self._bus is not None:
            self._bus.shutdown()
            self._bus = None
