"""Register image: layout, units, Modbus views (002 §2.3, §3.1, §3.2; docs/fidelity.md)."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from pywsg.fieldbus.image import (
    CmdFlag,
    InputImage,
    OutputImage,
    bytes_to_registers,
    force_scale,
    registers_to_bytes,
)
from pywsg.protocol import GripperState, GState, Status, SystemFlag


def test_manual_example_holding_register_288_is_move_and_if6() -> None:
    # 002 §2.3: holding register 0 = 288 starts MOVE and sets IF6.
    image = OutputImage.from_registers([288, 0, 0, 0])
    assert image.cmdflags == CmdFlag.MOVE
    assert image.if_flags == 0x20  # IF6 is bit 5
    assert OutputImage(CmdFlag.MOVE, 0x20).registers()[0] == 288
    assert image.coils()[0] and image.coils()[8 + 5]
    assert sum(image.coils()) == 2


@pytest.mark.parametrize(("flag", "bit"), [
    (CmdFlag.MOVE, 0), (CmdFlag.GRIP, 1), (CmdFlag.RELEASE, 2), (CmdFlag.HOMING, 3),
    (CmdFlag.STOP_ACK, 4), (CmdFlag.FASTSTOP, 5), (CmdFlag.JOG_PLUS, 6), (CmdFlag.JOG_MINUS, 7),
])
def test_every_command_flag_position(flag: CmdFlag, bit: int) -> None:
    image = OutputImage(flag)
    assert image.pack()[0] == 1 << bit
    assert image.registers()[0] == (1 << bit) << 8
    coils = image.coils()
    assert coils[bit] and sum(coils) == 1
    assert OutputImage().with_coils(bit, [True]).cmdflags == flag


def test_output_units_and_layout() -> None:
    # 002 §3.1 examples: 1220 = 12.20 mm, 3005 = 30.05 mm/s, 1050 = 10.50 N.
    image = OutputImage.from_units(CmdFlag.GRIP, width_mm=12.2, speed_mm_s=30.05, force_n=10.5)
    assert (image.width, image.speed, image.force_limit) == (1220, 3005, 1050)
    assert image.pack() == bytes([0x02, 0x00]) + (1220).to_bytes(2, "big") + (3005).to_bytes(2, "big") \
        + (1050).to_bytes(2, "big")
    assert image.registers() == [0x0200, 1220, 3005, 1050]
    assert image.width_mm == pytest.approx(12.2) and image.speed_mm_s == pytest.approx(30.05)
    assert image.force_n() == pytest.approx(10.5)
    # SPEED is unsigned: 40000 (the demo's 400 mm/s) is above int16 and still fits.
    assert OutputImage.from_units(speed_mm_s=400.0).registers()[2] == 40000
    # WIDTH is signed.
    assert OutputImage.from_registers([0, 0xFFFF, 0, 0]).width == -1


def test_wsg70_force_is_in_tenths_of_a_newton() -> None:
    assert force_scale("wsg70") == 10 and force_scale("WSG 70") == 10 and force_scale("wsg50") == 100
    image = OutputImage.from_units(force_n=305.0, model="wsg70")
    assert image.force_limit == 3050   # 002: 3050 means 305.0 N on the WSG 70
    assert image.force_n("wsg70") == pytest.approx(305.0)
    assert image.force_n("wsg50") == pytest.approx(30.5)
    inputs = InputImage.from_state(GripperState.HOLDING, SystemFlag.NONE, 20.0, 305.0, 0, model="wsg70")
    assert inputs.force == 3050 and inputs.force_n("wsg70") == pytest.approx(305.0)
    assert InputImage.from_state(GripperState.HOLDING, SystemFlag.NONE, 20.0, 40.5, 0).force == 4050


def test_values_that_do_not_fit_are_rejected_on_the_plc_side() -> None:
    with pytest.raises(ValueError, match="width"):
        OutputImage.from_units(width_mm=400.0)     # 40000 > int16
    with pytest.raises(ValueError, match="speed"):
        OutputImage.from_units(speed_mm_s=-1.0)
    with pytest.raises(ValueError, match="force"):
        OutputImage.from_units(force_n=400.0)      # 1/100 N on a WSG 50: 40000 > int16
    with pytest.raises(ValueError):
        OutputImage.unpack(b"\x00" * 7)
    with pytest.raises(IndexError):
        OutputImage().with_coils(15, [True, True])


def test_input_image_layout_and_units() -> None:
    flags = SystemFlag.SF_REFERENCED | SystemFlag.SF_FAST_STOP | SystemFlag.SF_SCRIPT_FAILURE
    image = InputImage.from_state(GripperState.HOLDING, flags, 12.2, 40.5, Status.E_CMD_PENDING, of_flags=0x81)
    data = image.pack()
    assert len(data) == 12
    assert data[0] == GState.HOLDING == 0x10 and data[1] == 0x81
    # 002 §2.3 / App. D: flag bit n is byte 2 + n // 8, bit n % 8 (REFERENCED byte 2 bit 0,
    # FAST_STOP = bit 12 byte 3 bit 4, SCRIPT_FAILURE = bit 20 byte 4 bit 4).
    assert data[2:6] == bytes([0x01, 0x10, 0x10, 0x00])
    assert int.from_bytes(data[6:8], "big") == 1220
    assert int.from_bytes(data[8:10], "big") == 4050
    assert int.from_bytes(data[10:12], "big") == 26
    regs = image.registers()
    assert regs == [0x1081, 0x0110, 0x1000, 1220, 4050, 26]
    assert InputImage.from_registers(regs) == image
    assert image.state == GripperState.HOLDING and image.status_code == Status.E_CMD_PENDING


def test_gstate_is_one_hot() -> None:
    for state in GripperState:
        image = InputImage.from_state(state, SystemFlag.NONE, 0.0, 0.0, 0)
        assert image.pack()[0] == 1 << int(state)
        assert image.state == state


def test_discrete_inputs_follow_the_flag_order() -> None:
    """002 §2.3: discrete inputs in the natural order of the bits, starting with byte 0 bit 0."""
    image = InputImage(GState.IDLE, 0x02, SystemFlag.SF_REFERENCED | SystemFlag.SF_FAST_STOP)
    di = image.discrete_inputs()
    assert len(di) == 48
    assert [i for i, b in enumerate(di) if b] == [0, 9, 16, 28]   # IDLE, OF2, REFERENCED, FAST_STOP
    data = image.pack()
    assert di == [bool(data[i // 8] >> (i % 8) & 1) for i in range(48)]


def test_negative_width_saturates_on_the_device_side() -> None:
    image = InputImage.from_state(GripperState.IDLE, SystemFlag.NONE, -0.5, 1e9, 0)
    assert image.width == -50 and image.force == 0x7FFF


@given(st.binary(min_size=8, max_size=8))
def test_output_roundtrip(data: bytes) -> None:
    image = OutputImage.unpack(data)
    assert image.pack() == data
    assert OutputImage.from_registers(image.registers()) == image
    assert registers_to_bytes(bytes_to_registers(data)) == data
    rebuilt = OutputImage(width=image.width, speed=image.speed, force_limit=image.force_limit)
    assert rebuilt.with_coils(0, image.coils()) == image


@given(st.binary(min_size=12, max_size=12))
def test_input_roundtrip(data: bytes) -> None:
    assert InputImage.unpack(data).pack() == data
    assert InputImage.from_registers(InputImage.unpack(data).registers()).pack() == data


def test_cmdflags_print_their_names() -> None:
    """CMDFLAGS (002 §3.1, output byte 0) print as names, like SystemFlag: a register 0120h is MOVE."""
    assert str(OutputImage.from_registers([0x0120, 0, 0, 0]).cmdflags) == "MOVE"
    assert str(CmdFlag.GRIP | CmdFlag.FASTSTOP) == "GRIP|FASTSTOP"
    assert str(CmdFlag(0)) == "NONE"
    assert f"{CmdFlag.HOMING:#04x}" == "0x08"  # a format spec still formats the number
