"""Cyclic RT_CLASS_1 frames of one IO AR, sans-IO (IEC 61158-6-10 §4.7).

A frame: FrameID (2), C_SDU of the IOCR's DataLength (each submodule's data then its IOPS, and the
IOCS for the other direction, at the offsets the controller gave in its IOCR blocks), CycleCounter (2,
in 31.25 µs units), DataStatus (1), TransferStatus (1).
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

from . import blocks as b
from .ar import AR, INPUT_LENGTH, OUTPUT_LENGTH
from .ether import ETH_P_PNIO, ether

IOXS_GOOD, IOXS_BAD = 0x80, 0x00
# DataStatus bits: State (primary), DataValid, ProviderState (1 RUN, 0 STOP), StationProblemIndicator
# (1 normal operation, 0 a problem: pending diagnosis)
DS_PRIMARY, DS_VALID, DS_RUN, DS_STATION_OK = 0x01, 0x04, 0x10, 0x20
DS_DEVICE = DS_PRIMARY | DS_VALID | DS_RUN | DS_STATION_OK   # 35h
WSG = (1, 1)
#: The substitute values the device uses for the WSG's outputs while the controller's are not valid
#: (ProviderState STOP, DataValid 0 or IOPS BAD): a zero output image (docs/fidelity.md "Substitute values").
SUBSTITUTE = bytes(OUTPUT_LENGTH)


@dataclass
class OutputData:
    """What one received output frame carried."""

    cycle_counter: int
    data_status: int
    outputs: bytes | None     # the 8 output bytes, None when IOPS or DataStatus say they are not valid
    why: str = ""             # why not valid ("" when valid)


class CyclicCodec:
    """Builds the input frames and reads the output frames of ``ar`` (layout checked at Connect)."""

    def __init__(self, ar: AR, mac: bytes) -> None:
        assert ar.input_cr is not None and ar.output_cr is not None
        self.ar = ar
        self.mac = mac
        self.in_cr, self.out_cr = ar.input_cr, ar.output_cr
        self.step = self.in_cr.send_clock_factor * self.in_cr.reduction_ratio
        self.cycle_counter = 0
        self._wsg_in = next((o.offset for o in self.in_cr.data if (o.slot, o.subslot) == WSG), None) \
            if ar.wsg_ok else None
        self._wsg_out = next((o.offset for o in self.out_cr.data if (o.slot, o.subslot) == WSG), None) \
            if ar.wsg_ok else None
        self._template = bytearray(self.in_cr.data_length)
        self._iops_offsets = []
        for o in self.in_cr.data:
            exp = ar.expected.get((o.slot, o.subslot))
            length = exp.input_length if exp else 0
            self._iops_offsets.append((o.offset + length, (o.slot, o.subslot) in ar.proper))
        self.provider_ok = False   # IOPS GOOD only once the application is ready
        self.station_problem = False   # a diagnosis is pending: DataStatus.StationProblemIndicator 0
        self.header = ether(ar.controller_mac, mac, ETH_P_PNIO, b"", tag=True)[:18]

    def input_frame(self, inputs: bytes) -> bytes:
        """The next input frame carrying the 12 input bytes."""
        c = self._template
        good = IOXS_GOOD if self.provider_ok else IOXS_BAD
        for off, proper in self._iops_offsets:
            c[off] = good if proper else IOXS_BAD
        for o in self.in_cr.iocs:   # we consume the controller's outputs: our IOCS
            c[o.offset] = IOXS_GOOD if (o.slot, o.subslot) in self.ar.proper else IOXS_BAD
        if self._wsg_in is not None:
            c[self._wsg_in:self._wsg_in + INPUT_LENGTH] = inputs[:INPUT_LENGTH]
        self.cycle_counter = (self.cycle_counter + self.step) & 0xFFFF
        frame = (self.header + struct.pack("!H", self.ar.input_frame_id) + bytes(c)
                 + struct.pack("!HBB", self.cycle_counter,
                               DS_DEVICE & ~DS_STATION_OK if self.station_problem else DS_DEVICE, 0))
        return frame + bytes(max(0, 64 - len(frame)))

    def output(self, payload: bytes) -> OutputData | None:
        """Parse an RT frame (after the EtherType); None when it is not this AR's output CR."""
        n = self.out_cr.data_length
        if len(payload) < 2 + n + 4 or int.from_bytes(payload[:2], "big") != self.ar.output_frame_id:
            return None
        counter, status, transfer = struct.unpack_from("!HBB", payload, 2 + n)
        off = self._wsg_out
        if not status & DS_RUN:
            why = f"ProviderState STOP (DataStatus {status:#04x})"
        elif not status & DS_VALID:
            why = f"DataValid 0 (DataStatus {status:#04x})"
        elif transfer:
            why = f"TransferStatus {transfer:#04x}"
        elif off is None:
            why = "no proper WSG submodule in this AR"
        elif not payload[2 + off + OUTPUT_LENGTH] & IOXS_GOOD:
            why = f"IOPS BAD ({payload[2 + off + OUTPUT_LENGTH]:#04x})"
        else:
            return OutputData(counter, status, payload[2 + off:2 + off + OUTPUT_LENGTH])
        return OutputData(counter, status, None, why)


class OutputConsumer:
    """The consumer's rule for the WSG's output data (IEC 61158-6-10 ProviderState / IOPS): valid
    outputs are used as they come; outputs the controller marks not valid (ProviderState STOP,
    DataValid 0, IOPS BAD) are replaced by :data:`SUBSTITUTE`, so a level (JOG+/JOG-) drops and no edge
    fires. Back to RUN with GOOD data, the first valid image is judged against the substitute image
    (a command bit still raised is a new edge)."""

    def __init__(self) -> None:
        self.applied: bytes | None = None   # the image last handed to the application
        self.substituting = ""              # why substitute values are in use ("" when not)

    def take(self, out: OutputData) -> bytes | None:
        """The output image the application must apply now, or None when it is unchanged."""
        image = out.outputs
        if image is None:
            self.substituting = out.why
            if self.applied is None:   # no valid outputs yet in this AR: nothing of the controller's to drop
                return None
            image = SUBSTITUTE
        else:
            self.substituting = ""
        if image == self.applied:
            return None
        self.applied = image
        return image


def is_output_cr(ar: AR) -> bool:
    return ar.output_cr is not None and ar.output_cr.iocr_type == b.IOCR_OUTPUT
