"""Diagnosis alarms over the AR's alarm CR (RTA on layer 2, low priority, frame ID FE01h), sans-IO.

The PROFINET counterpart of the PROFIBUS diagnosis message (002 §3.3 / 003 §4.2: one of the listed
error flags rising): a Diagnosis alarm (AlarmType 0001h) for the WSG submodule (slot 1, subslot 1)
with one ChannelDiagnosis item (USI 8000h, channel 8000h = the whole submodule), one alarm per flag:
"appears" (Specifier 1) when it rises; when it clears, "disappears, other remain" (AlarmType 0001h,
Specifier 3) while other listed flags stay, and "Diagnosis disappears" (AlarmType 000Ch, Specifier 2)
for the last one, so a controller's diagnosis buffer shows each fault and its end. The items:
:mod:`pywsg.fieldbus.profinet.diagnosis`.

RTA: one DATA-RTA-PDU outstanding (window 1), retransmitted every RTATimeoutFactor × 100 ms up to
RTARetries times; sequence numbers start at 0xFFFF and count modulo 0x8000, as profinet-py and p-net do.
"""

from __future__ import annotations

import logging
import struct
import time
from collections import deque
from dataclasses import dataclass

from . import blocks as b
from .ar import API, AR, WSG_MODULE, WSG_SUBMODULE
from .diagnosis import (
    APPEARS,
    DIAGNOSIS_FLAGS,
    DISAPPEARS,
    DISAPPEARS_OTHERS_REMAIN,
    ERROR_TYPES,
    USI_CHANNEL_DIAGNOSIS,
    channel_item,
)
from .ether import ETH_P_PNIO

log = logging.getLogger(__name__)

FID_ALARM_HIGH, FID_ALARM_LOW = 0xFC01, 0xFE01
RTA_DATA, RTA_NACK, RTA_ACK, RTA_ERR = 1, 2, 3, 4
WINDOW_1, TACK = 0x01, 0x10
SEQ_INIT, SEQ_INIT_O, SEQ_MASK = 0xFFFF, 0xFFFE, 0x7FFF
ALARM_NOTIFICATION_LOW = 0x0002
ALARM_DIAGNOSIS, ALARM_DIAGNOSIS_DISAPPEARS = 0x0001, 0x000C
__all__ = ["DIAGNOSIS_FLAGS", "ERROR_TYPES", "FID_ALARM_HIGH", "FID_ALARM_LOW", "AlarmChannel"]



@dataclass
class _Pending:
    pdu: bytes          # RTA-SDU (the AlarmNotification block)
    tries: int
    due: float


class AlarmChannel:
    """The device's end of one AR's alarm CR. :meth:`flags` feeds SYSSTATE; :meth:`poll` and
    :meth:`handle` return Ethernet frames to send."""

    def __init__(self, ar: AR, mac: bytes, local_ref: int) -> None:
        assert ar.alarm is not None
        self.ar = ar
        self.mac = mac
        self.dst_ref, self.src_ref = ar.alarm.local_ref, local_ref
        self.timeout = max(ar.alarm.timeout_factor, 1) * 0.1
        self.retries = ar.alarm.retries
        self.tag = struct.pack("!HH", 0x8100, ar.alarm.tag_low)
        self.send_seq, self.send_seq_o = SEQ_INIT, SEQ_INIT_O
        self.exp_seq, self.exp_seq_o = SEQ_INIT, SEQ_INIT_O
        self.alarm_seq = 0
        self.queue: deque[bytes] = deque(maxlen=32)
        self.pending: _Pending | None = None
        self.active = 0          # listed flags currently reported as appeared
        self.sent = self.acked = 0
        self.failed = False      # retries used up: the device ends the AR

    # --- diagnosis ---------------------------------------------------------------------------------
    def flags(self, sysstate: int) -> None:
        """The current SYSSTATE: queue an alarm for listed flags that rose or cleared. A flag that clears
        while others stay is a Diagnosis alarm with Specifier 3 ("disappears, other remain"); the last
        one to clear is a "Diagnosis disappears" alarm (AlarmType 000Ch, Specifier 2)."""
        now = sysstate & DIAGNOSIS_FLAGS
        rose, cleared = now & ~self.active, self.active & ~now
        present = self.active
        for flag, error_type in ERROR_TYPES.items():
            if cleared & int(flag):
                present &= ~int(flag)
                if present | rose:
                    self.queue.append(self._notification(ALARM_DIAGNOSIS, error_type, DISAPPEARS_OTHERS_REMAIN,
                                                         True))
                else:
                    self.queue.append(self._notification(ALARM_DIAGNOSIS_DISAPPEARS, error_type, DISAPPEARS,
                                                         False))
        for flag, error_type in ERROR_TYPES.items():
            if rose & int(flag):
                self.queue.append(self._notification(ALARM_DIAGNOSIS, error_type, APPEARS, True))
        self.active = now

    def _notification(self, alarm_type: int, error_type: int, specifier: int, remaining: bool) -> bytes:
        """One alarm per flag: one ChannelDiagnosis item, as every controller parses it."""
        # AlarmSpecifier: sequence number, ChannelDiagnosis, SubmoduleDiagnosisState and ARDiagnosisState
        # (a fault is still present after this alarm)
        spec = (self.alarm_seq & 0x7FF) | 0x0800 | (0xA000 if remaining else 0)
        self.alarm_seq = (self.alarm_seq + 1) & 0x7FF
        body = struct.pack("!HIHHIIH", alarm_type, API, 1, 1, WSG_MODULE, WSG_SUBMODULE, spec)
        return b.header(ALARM_NOTIFICATION_LOW, body + struct.pack("!H", USI_CHANNEL_DIAGNOSIS)
                        + channel_item(error_type, specifier))

    # --- RTA -------------------------------------------------------------------------------------------
    def poll(self, now: float | None = None) -> list[bytes]:
        """Frames due now: the next queued alarm, or a retransmission."""
        now = time.monotonic() if now is None else now
        if self.failed:
            return []
        if self.pending is None:
            if not self.queue:
                return []
            self.pending = _Pending(self.queue.popleft(), 0, 0.0)
        p = self.pending
        if now < p.due:
            return []
        if p.tries > self.retries:
            self.failed = True
            log.warning("PROFINET: diagnosis alarm not acknowledged after %d retries", self.retries)
            return []
        p.tries += 1
        p.due = now + self.timeout
        self.sent += 1
        return [self._frame(RTA_DATA, WINDOW_1 | TACK, self.send_seq, self.exp_seq_o, p.pdu)]

    def handle(self, payload: bytes) -> list[bytes]:
        """An RTA-PDU from the controller (after the frame ID); the frames to answer with."""
        if len(payload) < 12:
            return []
        dst, _src, pdu_type, _flags, seq, ack, var_len = struct.unpack_from("!HHBBHHH", payload)
        if dst != self.src_ref or pdu_type >> 4 != 1:
            return []
        kind = pdu_type & 0x0F
        if kind in (RTA_DATA, RTA_ACK) and self.pending is not None and ack == self.send_seq:
            self.send_seq_o, self.send_seq = self.send_seq, (self.send_seq + 1) & SEQ_MASK
            self.pending = None
            self.acked += 1
        if kind == RTA_ERR:
            log.info("PROFINET: the controller ended the alarm CR (ERR-RTA)")
            return []
        if kind != RTA_DATA or var_len > len(payload) - 12:
            return []
        if seq == self.exp_seq:   # e.g. the controller's AlarmAck: take it and confirm the transport
            self.exp_seq_o, self.exp_seq = self.exp_seq, (self.exp_seq + 1) & SEQ_MASK
        elif seq != self.exp_seq_o:
            return [self._frame(RTA_NACK, WINDOW_1, self.send_seq_o, self.exp_seq_o, b"")]
        return [self._frame(RTA_ACK, WINDOW_1, self.send_seq_o, self.exp_seq_o, b"")]

    def _frame(self, kind: int, flags: int, seq: int, ack: int, pdu: bytes) -> bytes:
        rta = struct.pack("!HHHBBHHH", FID_ALARM_LOW, self.dst_ref, self.src_ref, 0x10 | kind, flags, seq, ack,
                          len(pdu)) + pdu
        frame = self.ar.controller_mac + self.mac + self.tag + struct.pack("!H", ETH_P_PNIO) + rta
        return frame + bytes(max(0, 64 - len(frame)))
