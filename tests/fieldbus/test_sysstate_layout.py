"""SYSSTATE as the PLC sees it (002 §2.3, §3.2, §3.3, Appendix D "WSG_RECEIVE"; 003 §4.1.2).

The decoder below is written from the manual's SCL listing, the way an S7 PLC maps a received
byte block onto ``WSG_RECEIVE``: the Bools of a Struct fill byte 0 bit 0, bit 1, … then the next
byte; ``Int``/``UInt`` are big-endian. It shares no code with pywsg's own unpacking. Every view
of the input image (input registers, discrete inputs, Fieldbus Monitor, PROFIBUS diagnosis) must
decode to the same flags through it.
"""

from __future__ import annotations

import asyncio
import time
from collections.abc import AsyncIterator

import pytest
from hypothesis import given
from hypothesis import strategies as st

from pywsg.fieldbus.plc import GrippingCycle, WsgReceive
from pywsg.fieldbus.profibus import diagnosis_message
from pywsg.server import SimServer
from pywsg.web.fieldbus_view import fieldbus_view

from .raw_modbus import adu, exchange, registers

pytestmark = [pytest.mark.realtime, pytest.mark.pymodbus]  # pymodbus: also run on the oldest pin (scripts/test.sh)

# 002 Appendix D, TYPE "WSG_RECEIVE", lines 8..62 of the listing.
STW1 = ["IDLE", "GRASPING", "NO_PART", "PART_LOST", "HOLDING", "RELEASING", "POSITIONING", "ERROR", "OF1",
        "OF2", "OF3", "OF4", "OF5", "OF6", "OF7", "OF8"]
SYSSTATE = ["REFERENCED", "MOVING", "BLOCKED_MINUS", "BLOCKED_PLUS", "SOFT_LIMIT_MINUS", "SOFT_LIMIT_PLUS",
            "AXIS_STOPPED", "TARGET_POS_REACHED", "OVERDRIVE_MODE", "FORCECNTL_MODE", "RES10", "RES11",
            "FAST_STOP", "TEMP_WARNING", "TEMP_FAULT", "POWER_FAULT", "CURR_FAULT", "FINGER_FAULT",
            "CMD_FAILURE", "SCRIPT_RUN", "SCRIPT_FAILURE", "RES21", "RES22", "RES23", "RES24", "RES25",
            "RES26", "RES27", "RES28", "RES29", "RES30", "RES31"]


def s7_bools(block: bytes, names: list[str]) -> dict[str, bool]:
    """A Struct of Bools over ``block``: the k-th Bool is byte k // 8, bit k % 8."""
    return {name: bool(block[k // 8] & (1 << (k % 8))) for k, name in enumerate(names)}


def s7_receive(data: bytes) -> dict[str, object]:
    """WSG_RECEIVE as an S7 PLC reads the 12 input bytes."""
    assert len(data) == 12
    return {"STW1": s7_bools(data[0:2], STW1), "SYSSTATE": s7_bools(data[2:6], SYSSTATE),
            "WIDTH": int.from_bytes(data[6:8], "big", signed=True),
            "FORCE": int.from_bytes(data[8:10], "big"), "ERROR_CODE": int.from_bytes(data[10:12], "big")}


def read_input_bytes(port: int) -> bytes:
    """FC4, input registers 0..5, on a raw socket; the 12 data bytes exactly as they came."""
    ((_, pdu),) = exchange(port, adu(bytes([4, 0, 0, 0, 6])))
    assert pdu[:2] == bytes([4, 12])
    return pdu[2:]


def read_discrete_inputs(port: int) -> list[bool]:
    """FC2, discrete inputs 0..47, on a raw socket (Modbus packs input i into byte i // 8, bit i % 8)."""
    ((_, pdu),) = exchange(port, adu(bytes([2, 0, 0, 0, 48])))
    assert pdu[:2] == bytes([2, 6])
    return [bool(pdu[2 + i // 8] >> (i % 8) & 1) for i in range(48)]


@pytest.fixture
async def sim() -> AsyncIterator[SimServer]:
    async with SimServer(tcp_port=None, udp_port=None, modbus_port=0) as s:
        yield s


async def _home(port: int) -> dict[str, object]:
    await asyncio.to_thread(exchange, port, adu(bytes([6, 0, 0, 0x08, 0x00])))   # HR0: HOMING
    await asyncio.to_thread(exchange, port, adu(bytes([6, 0, 0, 0, 0])))
    deadline = time.monotonic() + 10
    while True:
        plc = s7_receive(await asyncio.to_thread(read_input_bytes, port))
        stw1 = plc["STW1"]
        assert isinstance(stw1, dict)
        if stw1["IDLE"] and plc["ERROR_CODE"] == 0:
            return plc
        assert time.monotonic() < deadline, plc
        await asyncio.sleep(0.01)


async def test_plc_sees_referenced_after_homing(sim: SimServer) -> None:
    """002 App. D: the listing's step 2 waits for ``receive.SYSSTATE.REFERENCED`` — it must come true."""
    port = sim.modbus_port or 0
    before = s7_receive(await asyncio.to_thread(read_input_bytes, port))
    assert before["SYSSTATE"]["REFERENCED"] is False  # type: ignore[index]
    plc = await _home(port)
    sysstate = plc["SYSSTATE"]
    assert isinstance(sysstate, dict)
    assert sysstate["REFERENCED"] and not sysstate["MOVING"] and not sysstate["FAST_STOP"]
    data = await asyncio.to_thread(read_input_bytes, port)
    assert data[2] & 0x01                                   # REFERENCED: image byte 2, bit 0
    regs = registers(bytes([4, 12]) + data)
    assert regs[1] >> 8 == data[2] and regs[1] & 0x100      # IR1 high byte = image byte 2

    # discrete inputs: input 16 + n is SYSSTATE bit n, the same bit as byte 2 + n // 8, bit n % 8
    di = await asyncio.to_thread(read_discrete_inputs, port)
    assert di[16] is True
    assert di == [bool(data[i // 8] >> (i % 8) & 1) for i in range(48)]
    assert [di[16 + k] for k in range(32)] == [sysstate[name] for name in SYSSTATE]


async def test_every_view_agrees_under_fast_stop(sim: SimServer) -> None:
    """FAST_STOP is SYSSTATE bit 12: byte 3 bit 4, discrete input 28, diagnosis byte 8 bit 4 (002 §3.3)."""
    port = sim.modbus_port or 0
    await _home(port)
    await asyncio.to_thread(exchange, port, adu(bytes([5, 0, 5, 0xFF, 0x00])))   # coil 5: FASTSTOP
    data = await asyncio.to_thread(read_input_bytes, port)
    plc = s7_receive(data)
    sysstate = plc["SYSSTATE"]
    assert isinstance(sysstate, dict)
    assert sysstate["FAST_STOP"] and sysstate["REFERENCED"] and data[3] & 0x10
    di = await asyncio.to_thread(read_discrete_inputs, port)
    assert di[28] and di[16]

    # Fieldbus Monitor (Diagnosis page): the same bytes, and its decoded flags are the PLC's
    view = fieldbus_view(sim.grippers[0].modbus)
    shown = bytes(int(b["hex"][:2], 16) for b in view["input"]["bytes"])
    assert shown[2:6] == data[2:6]
    named = {f.removeprefix("SF_") for f in view["input"]["registers"][2]["flags"]}
    assert {"REFERENCED", "FAST_STOP"} <= named
    assert {n for n, on in sysstate.items() if on} == {n.replace("SCRIPT_RUNNING", "SCRIPT_RUN") for n in named}

    # PROFIBUS diagnosis bytes 7..10: "same coding as SYSSTATE"
    flags = sim.grippers[0].modbus.controller.input_image().sysstate
    msg = diagnosis_message(flags)
    assert msg[7:11] == data[2:6]
    assert s7_bools(msg[7:11], SYSSTATE) == sysstate


@given(st.binary(min_size=12, max_size=12))
def test_the_plc_demo_reads_the_struct_like_an_s7(data: bytes) -> None:
    """`wsg plc-demo`'s WSG_RECEIVE port agrees with the independent decoder on any 12 bytes."""
    ours = WsgReceive.from_bytes(data)
    theirs = s7_receive(data)
    assert {n: getattr(ours.STW1, n) for n in STW1} == theirs["STW1"]
    assert {n: getattr(ours.SYSSTATE, n) for n in SYSSTATE} == theirs["SYSSTATE"]
    assert (theirs["WIDTH"], theirs["FORCE"], theirs["ERROR_CODE"]) == (ours.WIDTH, ours.FORCE, ours.ERROR_CODE)


@pytest.mark.parametrize(("sysstate", "next_state"), [
    (bytes([0x01, 0, 0, 0]), 3),      # REFERENCED = byte 2 bit 0: the listing goes on to step 3
    (bytes([0, 0, 0, 0x01]), -1),     # the old big-endian word: REFERENCED false, error path
])
def test_listing_step_2_checks_referenced_in_byte_2_bit_0(sysstate: bytes, next_state: int) -> None:
    """002 App. D step 2: ``IF #receive.STW1.IDLE = true THEN IF #receive.SYSSTATE.REFERENCED = false
    THEN #state := -1``."""
    cycle = GrippingCycle(state=2)
    cycle.step(WsgReceive.from_bytes(bytes([0x01, 0]) + sysstate + bytes(6)), 0.0)
    assert cycle.state == next_state
