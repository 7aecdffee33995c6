"""Finger interface (60h..63h, 70h..73h): types, flags, power control, data frames."""

from __future__ import annotations

import struct

import pytest

from pywsg.device import Settings
from pywsg.device.fingers import DSA_COLS, DSA_ROWS
from pywsg.protocol import FingerFlag, FingerType, Status

from .devrig import Rig, make_rig

S = Status


@pytest.mark.parametrize("base", [0x60, 0x70])
def test_generic_finger(rig: Rig, base: int) -> None:
    assert rig.value(base) == {"type": FingerType.GENERIC, "size": 0}
    assert rig.value(base + 1)["flags"] == FingerFlag.POWER_ON
    assert rig.status(base + 3) == S.E_NOT_AVAILABLE
    assert rig.status(base + 2, b"") == S.E_CMD_FORMAT_ERROR
    assert rig.status(base + 2, power=2) == S.E_INVALID_PARAMETER


@pytest.mark.parametrize("base", [0x60, 0x70])
def test_power_control_pending_then_success_after_500ms(rig: Rig, base: int) -> None:
    assert rig.status(base + 2, power=0) == S.E_SUCCESS  # switching off: immediate
    assert not rig.value(base + 1)["flags"] & FingerFlag.POWER_ON
    assert rig.status(base + 2, power=1) == S.E_CMD_PENDING
    assert rig.status(base + 2, power=1) == S.E_ALREADY_RUNNING
    assert rig.g.next_due() == pytest.approx(0.5)
    assert rig.run(0.49) == []
    out = rig.run(0.02)
    assert [(f.command_id, f.status) for f in out] == [(base + 2, S.E_SUCCESS)]
    assert rig.value(base + 1)["flags"] & FingerFlag.POWER_ON


def test_fmf_finger_data_frame() -> None:
    r = make_rig(settings=Settings(finger1="fmf", finger2="fmf"))
    assert r.value(0x60) == {"type": FingerType.WSG_FMF, "size": 4}
    assert r.value(0x61)["flags"] == FingerFlag.POWER_ON | FingerFlag.CONFIG_AVAIL | FingerFlag.COMM_OPEN
    assert r.status(0x62, power=0) == S.E_ACCESS_DENIED  # predefined fingers cannot be switched
    (force,) = struct.unpack("<f", r.call(0x73).params)
    assert force == pytest.approx(0.2)  # untared zero drift
    r.g.faults.finger_fault(0, True)
    assert r.status(0x63) == S.E_IO_ERROR


def test_dsa_finger_data_frame() -> None:
    r = make_rig(settings=Settings(finger2="dsa"))
    size = DSA_ROWS * DSA_COLS * 2
    assert r.value(0x70) == {"type": FingerType.WSG_DSA, "size": size}
    idle = struct.unpack(f"<{DSA_ROWS * DSA_COLS}H", r.call(0x73).params)
    assert not any(idle)
    r.home()
    r.g.faults.place_part(40.0)
    r.status(0x25, width=40.0, speed=100.0)
    r.run(5)
    data = r.call(0x73).params
    assert len(data) == size
    cells = struct.unpack(f"<{DSA_ROWS * DSA_COLS}H", data)
    assert max(cells) == 1600 and sum(1 for c in cells if c) == 24


@pytest.mark.parametrize("cid", [0x60, 0x61, 0x63, 0x70, 0x71, 0x73])
def test_finger_command_with_stray_payload_is_format_error(rig: Rig, cid: int) -> None:
    """000 §3.6.1–3.6.8 list only E_CMD_FORMAT_ERROR ("Command length mismatch") for a wrong length:
    the command's own list wins over the generic E_NO_PARAM_EXPECTED (issue 12 item 7)."""
    assert rig.status(cid, b"\x00") == S.E_CMD_FORMAT_ERROR
    assert rig.status(cid, b"\x01\x02\x03") == S.E_CMD_FORMAT_ERROR
    assert rig.status(0x31, b"\x00") == S.E_NO_PARAM_EXPECTED  # 31h lists E_NO_PARAM_EXPECTED (000 §3.3.2)
