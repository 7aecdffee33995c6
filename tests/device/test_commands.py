"""Every command of chapter 3 with each status code the manual lists for it (ManualClock)."""

from __future__ import annotations

import math
import struct

import pytest

from pywsg.device import Settings, encode_fw_version
from pywsg.protocol import CATALOG, DeviceType, Frame, GripperState, Status, SystemFlag

from .devrig import Rig, make_rig

S = Status
SF = SystemFlag


# 3.1.1 Loop
def test_loop_returns_payload(rig: Rig) -> None:
    data = bytes(range(256))
    reply = rig.call(0x06, data)
    assert reply.status == S.E_SUCCESS and reply.params == data


def test_loop_over_256_bytes_is_format_error(rig: Rig) -> None:
    assert rig.status(0x06, bytes(257)) == S.E_CMD_FORMAT_ERROR


def test_loop_without_data_is_invalid_parameter(rig: Rig) -> None:
    assert rig.status(0x06, b"") == S.E_INVALID_PARAMETER


# 3.1.2 Disconnect announcement
def test_disconnect_then_everything_denied(rig: Rig) -> None:
    assert rig.status(0x07) == S.E_SUCCESS
    for cid, payload in ((0x06, b"x"), (0x40, b"\x00\x00\x00"), (0x50, b""), (0x99, b"")):
        assert rig.status(cid, payload) == S.E_ACCESS_DENIED


def test_disconnect_with_parameter(rig: Rig) -> None:
    assert rig.status(0x07, b"\x01") == S.E_NO_PARAM_EXPECTED


def test_disconnect_not_available_on_udp() -> None:
    r = make_rig(kind="udp")
    assert r.status(0x07) == S.E_NOT_AVAILABLE


def test_disconnect_aborts_running_motion(homed: Rig) -> None:
    assert homed.status(0x21, flags=0, width=10.0, speed=20.0) == S.E_CMD_PENDING
    homed.clock.advance(0.5)
    replies = homed.send(0x07)
    assert [(f.command_id, f.status) for f in replies] == [(0x21, S.E_CMD_ABORTED), (0x07, S.E_SUCCESS)]
    assert not homed.g.moving()


# 3.2.1 Homing
def test_homing_statuses(rig: Rig) -> None:
    assert rig.status(0x20, b"") == S.E_CMD_FORMAT_ERROR
    assert rig.status(0x20, direction=3) == S.E_INVALID_PARAMETER
    assert rig.status(0x20, direction=2) == S.E_CMD_PENDING
    assert rig.status(0x20, direction=2) == S.E_ALREADY_RUNNING
    assert [f.status for f in rig.run(5)] == [S.E_SUCCESS]
    assert rig.width() == 0.0 and rig.flags() & SF.SF_REFERENCED


def test_homing_default_direction_from_settings() -> None:
    r = make_rig(settings=Settings(homing_direction=2))
    r.home()
    assert r.g.true_width() == 0.0
    r2 = make_rig(settings=Settings(homing_direction=1))
    r2.home()
    assert r2.width() == 110.0


def test_homing_denied_in_fast_stop(rig: Rig) -> None:
    assert rig.status(0x23) == S.E_SUCCESS
    assert rig.status(0x20, direction=0) == S.E_ACCESS_DENIED


def test_homing_aborted_by_stop(rig: Rig) -> None:
    rig.status(0x20, direction=1)
    rig.clock.advance(0.3)
    replies = rig.send(0x22)
    assert [(f.command_id, f.status) for f in replies] == [(0x20, S.E_CMD_ABORTED), (0x22, S.E_SUCCESS)]
    assert not rig.flags() & SF.SF_REFERENCED


def test_homing_ignores_soft_limits(homed: Rig) -> None:
    assert homed.status(0x34, minus=10.0, plus=90.0) == S.E_SUCCESS
    assert homed.status(0x20, direction=1) == S.E_CMD_PENDING  # at 110, inside the restricted area
    assert [f.status for f in homed.run(5)] == [S.E_SUCCESS]
    assert not homed.flags() & SF.SF_FAST_STOP


# 3.2.2 Pre-position
def test_preposition_statuses(rig: Rig) -> None:
    assert rig.status(0x21, flags=0, width=10.0, speed=50.0) == S.E_NOT_INITIALIZED
    rig.home()
    assert rig.status(0x21, b"\x00" * 8) == S.E_CMD_FORMAT_ERROR
    assert rig.status(0x21, flags=0, width=10.0, speed=50.0) == S.E_CMD_PENDING
    assert rig.status(0x21, flags=0, width=20.0, speed=50.0) == S.E_ALREADY_RUNNING
    assert [f.status for f in rig.run(5)] == [S.E_SUCCESS]
    assert abs(rig.width() - 10.0) < 1e-6
    assert rig.flags() & SF.SF_TARGET_POS_REACHED


def test_preposition_relative_and_clamped(homed: Rig) -> None:
    homed.status(0x21, flags=1, width=-30.0, speed=100.0)
    homed.run(5)
    assert abs(homed.width() - 80.0) < 1e-6
    homed.status(0x21, flags=1, width=500.0, speed=100.0)  # beyond the stroke: clamped
    assert [f.status for f in homed.run(5)] == [S.E_SUCCESS]
    assert abs(homed.width() - 110.0) < 1e-6


def test_preposition_range_error_inside_soft_limits(homed: Rig) -> None:
    homed.status(0x34, minus=20.0, plus=100.0)
    homed.status(0x21, flags=0, width=50.0, speed=100.0)
    homed.run(5)
    assert homed.status(0x21, flags=0, width=10.0, speed=100.0) == S.E_RANGE_ERROR
    assert homed.status(0x21, flags=0, width=105.0, speed=100.0) == S.E_RANGE_ERROR
    assert homed.status(0x21, flags=0, width=20.0, speed=100.0) == S.E_CMD_PENDING  # on the limit: allowed


def test_preposition_stop_on_block(homed: Rig) -> None:
    homed.g.faults.block_at(60.0)
    homed.status(0x21, flags=2, width=20.0, speed=100.0)
    assert [f.status for f in homed.run(5)] == [S.E_AXIS_BLOCKED]
    assert abs(homed.width() - 60.0) < 1e-6
    assert homed.flags() & SF.SF_BLOCKED_MINUS
    assert homed.g.force() == 0.0
    assert homed.status(0x22) == S.E_SUCCESS
    assert not homed.flags() & SF.SF_BLOCKED_MINUS


def test_preposition_clamp_on_block_then_snap(homed: Rig) -> None:
    homed.g.faults.block_at(60.0)
    homed.status(0x21, flags=0, width=20.0, speed=100.0)
    assert [f.status for f in homed.run(5)] == [S.E_AXIS_BLOCKED]
    assert homed.g.force() == pytest.approx(40.0)  # 50 % of the nominal 80 N
    homed.g.faults.unblock()
    assert homed.flags() & SF.SF_MOVING
    assert homed.run(5) == []  # no further frame: the command already answered
    assert abs(homed.width() - 20.0) < 1e-6
    assert homed.g.force() == 0.0


def test_preposition_nan_is_invalid_parameter(homed: Rig) -> None:
    assert homed.status(0x21, flags=0, width=math.nan, speed=10.0) == S.E_INVALID_PARAMETER


# 3.2.3 Stop
def test_stop_statuses_and_axis_stopped(homed: Rig) -> None:
    assert homed.status(0x22, b"\x00") == S.E_NO_PARAM_EXPECTED
    homed.status(0x21, flags=0, width=0.0, speed=50.0)
    homed.clock.advance(1.0)
    w = homed.g.width()
    replies = homed.send(0x22)
    assert [f.status for f in replies] == [S.E_CMD_ABORTED, S.E_SUCCESS]
    assert homed.flags() & SF.SF_AXIS_STOPPED
    homed.clock.advance(1.0)
    assert homed.width() == pytest.approx(w, abs=1e-4)
    homed.status(0x21, flags=0, width=50.0, speed=50.0)
    assert not homed.flags() & SF.SF_AXIS_STOPPED  # cleared by the next motion command


# 3.2.4 / 3.2.5 FAST STOP and acknowledge
def test_fast_stop_and_ack(homed: Rig) -> None:
    homed.status(0x21, flags=0, width=10.0, speed=50.0)
    homed.clock.advance(0.5)
    replies = homed.send(0x23)
    assert [(f.command_id, f.status) for f in replies] == [(0x21, S.E_CMD_ABORTED), (0x23, S.E_SUCCESS)]
    assert homed.flags() & SF.SF_FAST_STOP
    assert homed.gstate() == GripperState.ERROR
    for cid, kw in ((0x21, dict(flags=0, width=50.0, speed=50.0)), (0x25, dict(width=5.0, speed=50.0)),
                    (0x26, dict(width=50.0, speed=50.0)), (0x20, dict(direction=0))):
        assert homed.status(cid, **kw) == S.E_ACCESS_DENIED
    assert homed.status(0x24, b"ACK") == S.E_CMD_FORMAT_ERROR
    assert homed.status(0x24, b"ac") == S.E_CMD_FORMAT_ERROR
    assert homed.flags() & SF.SF_FAST_STOP
    assert homed.status(0x24, b"ack") == S.E_SUCCESS
    assert not homed.flags() & SF.SF_FAST_STOP
    assert homed.status(0x21, flags=0, width=50.0, speed=50.0) == S.E_CMD_PENDING
    assert any("FAST STOP" in m for m in homed.g.log.messages())



# 3.2.6 Grip
def test_grip_statuses(rig: Rig) -> None:
    assert rig.status(0x25, width=10.0, speed=50.0) == S.E_NOT_INITIALIZED
    rig.home()
    assert rig.status(0x25, b"\x00" * 7) == S.E_CMD_FORMAT_ERROR
    rig.g.faults.place_part(30.0)
    assert rig.status(0x25, width=30.0, speed=80.0) == S.E_CMD_PENDING
    assert rig.status(0x25, width=30.0, speed=80.0) == S.E_ALREADY_RUNNING
    assert [f.status for f in rig.run(5)] == [S.E_SUCCESS]
    assert rig.gstate() == GripperState.HOLDING
    assert rig.g.force() == pytest.approx(80.0)


def test_grip_without_part_fails(homed: Rig) -> None:
    homed.status(0x25, width=30.0, speed=80.0)
    assert [f.status for f in homed.run(5)] == [S.E_CMD_FAILED]
    assert homed.gstate() == GripperState.NO_PART
    assert abs(homed.width() - 25.0) < 1e-6  # nominal minus the 5 mm clamping travel
    assert homed.flags() & SF.SF_CMD_FAILURE


def test_grip_range_error_on_soft_limits(homed: Rig) -> None:
    homed.status(0x34, minus=20.0, plus=100.0)
    assert homed.status(0x25, width=10.0, speed=80.0) == S.E_RANGE_ERROR


def test_grip_aborted(homed: Rig) -> None:
    homed.status(0x25, width=30.0, speed=80.0)
    homed.clock.advance(0.2)
    assert [f.status for f in homed.send(0x22)] == [S.E_CMD_ABORTED, S.E_SUCCESS]


def test_grip_against_held_part_is_denied_regrip_same_direction_allowed(homed: Rig) -> None:
    homed.g.faults.place_part(30.0)
    homed.status(0x25, width=30.0, speed=80.0)
    homed.run(5)
    assert homed.status(0x25, width=60.0, speed=80.0) == S.E_ACCESS_DENIED  # would open
    assert homed.status(0x25, width=28.0, speed=80.0) == S.E_CMD_PENDING  # re-grip, same direction
    assert [f.status for f in homed.run(5)] == [S.E_SUCCESS]
    assert homed.gstate() == GripperState.HOLDING


def test_grip_part_too_big_for_clamping_travel_is_no_part(homed: Rig) -> None:
    homed.g.faults.place_part(50.0)
    homed.status(0x25, width=30.0, speed=80.0)
    assert [f.status for f in homed.run(5)] == [S.E_CMD_FAILED]
    assert homed.gstate() == GripperState.NO_PART


def test_inside_grip_opens_onto_the_part(homed: Rig) -> None:
    homed.status(0x21, flags=0, width=10.0, speed=100.0)
    homed.run(5)
    homed.g.faults.place_part(40.0, inside=True)  # a ring around the fingers
    homed.status(0x25, width=40.0, speed=80.0)
    assert [f.status for f in homed.run(5)] == [S.E_SUCCESS]
    assert homed.gstate() == GripperState.HOLDING
    assert homed.width() == pytest.approx(40.0)  # on the ring (a rigid part by default)


# 3.2.7 Release
def test_release_statuses(homed: Rig) -> None:
    assert homed.status(0x26, b"\x00" * 9) == S.E_CMD_FORMAT_ERROR
    homed.status(0x34, minus=5.0, plus=100.0)
    assert homed.status(0x26, width=105.0, speed=50.0) == S.E_RANGE_ERROR
    homed.status(0x36)
    assert homed.status(0x26, width=80.0, speed=50.0) == S.E_CMD_PENDING
    assert homed.status(0x26, width=80.0, speed=50.0) == S.E_ALREADY_RUNNING
    homed.clock.advance(0.1)
    assert [f.status for f in homed.send(0x22)] == [S.E_CMD_ABORTED, S.E_SUCCESS]
    homed.status(0x26, width=80.0, speed=50.0)
    assert [f.status for f in homed.run(5)] == [S.E_SUCCESS]


# 3.3 motion configuration
def test_acceleration_set_get_clamped(rig: Rig) -> None:
    assert rig.value(0x31)["acceleration"] == 5000.0  # the default (docs/fidelity.md)
    assert rig.status(0x30, acceleration=150.0) == S.E_SUCCESS
    assert rig.value(0x31)["acceleration"] == 150.0
    assert rig.status(0x30, acceleration=1e6) == S.E_SUCCESS
    assert rig.value(0x31)["acceleration"] == 5000.0
    assert rig.status(0x30, acceleration=1.0) == S.E_SUCCESS
    assert rig.value(0x31)["acceleration"] == 100.0
    assert rig.status(0x30, b"\x00\x00") == S.E_CMD_FORMAT_ERROR
    assert rig.status(0x31, b"\x00") == S.E_NO_PARAM_EXPECTED


def test_get_acceleration_reply_bytes_match_manual_example(rig: Rig) -> None:
    # manual 1.2.2 example 3: E_SUCCESS + 150.0 (00 00 16 43), once 150 mm/s² is set (30h)
    assert rig.status(0x30, acceleration=150.0) == S.E_SUCCESS
    assert rig.call(0x31).payload == bytes.fromhex("0000 00001643")


def test_force_limit_set_get_clamped_and_overdrive(rig: Rig) -> None:
    assert rig.value(0x33)["force"] == 80.0
    rig.status(0x32, force=1.0)
    assert rig.value(0x33)["force"] == 5.0
    rig.status(0x32, force=200.0)
    assert rig.value(0x33)["force"] == 80.0
    assert rig.status(0x37, flags=1) == S.E_SUCCESS
    assert rig.flags() & SF.SF_OVERDRIVE_MODE
    rig.status(0x32, force=200.0)
    assert rig.value(0x33)["force"] == 120.0
    assert rig.status(0x37, flags=0) == S.E_SUCCESS
    assert rig.value(0x33)["force"] == 80.0  # reduced when overdrive is left
    assert not rig.flags() & SF.SF_OVERDRIVE_MODE
    assert [m for m in rig.g.log.messages() if "overdrive" in m] == ["overdrive mode entered", "overdrive mode left"]
    assert rig.status(0x32, b"") == S.E_CMD_FORMAT_ERROR
    assert rig.status(0x33, b"\x00") == S.E_NO_PARAM_EXPECTED
    assert rig.status(0x37, b"") == S.E_CMD_FORMAT_ERROR
    assert rig.status(0x37, b"\x02") == S.E_INVALID_PARAMETER


def test_soft_limits_set_get_clear(rig: Rig) -> None:
    assert rig.status(0x35) == S.E_NOT_AVAILABLE
    assert rig.status(0x34, minus=10.0, plus=90.0) == S.E_SUCCESS
    assert rig.value(0x35) == {"minus": 10.0, "plus": 90.0}
    assert rig.status(0x35, b"\x00") == S.E_NO_PARAM_EXPECTED
    assert rig.status(0x36, b"\x00") == S.E_NO_PARAM_EXPECTED
    assert rig.status(0x36) == S.E_SUCCESS
    assert rig.status(0x35) == S.E_NOT_AVAILABLE
    assert rig.status(0x34, b"\x00" * 4) == S.E_CMD_FORMAT_ERROR
    assert rig.status(0x34, minus=90.0, plus=10.0) == S.E_INVALID_PARAMETER


def test_soft_limit_flags(homed: Rig) -> None:
    homed.status(0x34, minus=10.0, plus=90.0)
    assert homed.flags() & SF.SF_SOFT_LIMIT_PLUS  # homed at 110
    homed.status(0x21, flags=0, width=50.0, speed=100.0)  # moving out of the restricted area: allowed
    homed.run(5)
    f = homed.flags()
    assert not f & (SF.SF_SOFT_LIMIT_PLUS | SF.SF_SOFT_LIMIT_MINUS)
    homed.status(0x21, flags=0, width=10.0, speed=100.0)
    homed.run(5)
    assert homed.flags() & SF.SF_SOFT_LIMIT_MINUS


def test_tare(rig: Rig) -> None:
    assert rig.status(0x38) == S.E_NOT_AVAILABLE  # generic fingers: no force sensor
    assert rig.status(0x38, b"\x00") == S.E_NO_PARAM_EXPECTED
    r = make_rig(settings=Settings(finger1="fmf"))
    before = struct.unpack("<f", r.call(0x63).params)[0]
    assert before == pytest.approx(0.2)
    assert r.status(0x38) == S.E_SUCCESS
    assert struct.unpack("<f", r.call(0x63).params)[0] == pytest.approx(0.0, abs=1e-6)
    r.home()
    r.g.faults.place_part(30.0)
    r.status(0x25, width=30.0, speed=100.0)
    r.run(5)
    assert r.flags() & SF.SF_FORCECNTL_MODE
    assert r.status(0x38) == S.E_ACCESS_DENIED  # HOLDING: force control mode
    assert struct.unpack("<f", r.call(0x63).params)[0] == pytest.approx(80.0)


# 3.4 system state
@pytest.mark.parametrize("cid", [0x40, 0x41, 0x43, 0x44, 0x45])
def test_state_queries_need_flags_and_period(rig: Rig, cid: int) -> None:
    assert rig.status(cid, b"") == S.E_CMD_FORMAT_ERROR
    assert rig.status(cid, b"\x00\x00") == S.E_CMD_FORMAT_ERROR
    assert rig.status(cid, flags=0, period_ms=0) == S.E_SUCCESS
    assert rig.status(cid, flags=1, period_ms=9) == S.E_INVALID_PARAMETER


def test_statistics_and_reset(homed: Rig) -> None:
    homed.status(0x25, width=30.0, speed=100.0)
    homed.run(5)  # no part
    homed.g.faults.place_part(50.0, inside=True)
    homed.status(0x25, width=50.0, speed=100.0)  # fingers at 25 open onto a ring of 50 mm
    homed.run(5)
    assert homed.gstate() == GripperState.HOLDING
    homed.g.faults.remove_part()
    assert homed.gstate() == GripperState.PART_LOST
    assert homed.value(0x42, flags=0) == {"total": 2, "no_part": 1, "lost_part": 1}
    assert homed.value(0x42, flags=1)["total"] == 2
    assert homed.value(0x42, flags=0) == {"total": 0, "no_part": 0, "lost_part": 0}
    assert homed.status(0x42, b"") == S.E_CMD_FORMAT_ERROR


def test_temperature_reading(rig: Rig) -> None:
    t = rig.value(0x46)["temperature"]
    assert t == 300  # 30.0 °C at rest
    assert rig.status(0x46, b"\x00") == S.E_NO_PARAM_EXPECTED


# 3.5 system configuration
def test_system_info(rig: Rig) -> None:
    v = rig.value(0x50)
    assert v["type"] == DeviceType.WSG50 and v["fw_version"] == encode_fw_version(4, 0, 2) == 0x4020
    assert v["sn"] == 10001 and v["hwrev"] == 1
    assert rig.status(0x50, b"\x00") == S.E_NO_PARAM_EXPECTED
    r = make_rig("wsg70", settings=Settings(serial_number=4242))
    assert r.value(0x50)["type"] == DeviceType.WSG70 and r.value(0x50)["sn"] == 4242


def test_device_tag(rig: Rig) -> None:
    assert rig.status(0x52) == S.E_NOT_AVAILABLE
    assert rig.status(0x51, b"cell 4 / station B") == S.E_SUCCESS
    assert rig.value(0x52)["tag"] == "cell 4 / station B"
    assert rig.status(0x51, b"x" * 64) == S.E_SUCCESS
    assert rig.status(0x51, b"x" * 65) == S.E_OVERRUN
    assert rig.status(0x51, b"bad\ntag") == S.E_INVALID_PARAMETER
    assert rig.status(0x51, b"caf\xe9") == S.E_INVALID_PARAMETER
    assert rig.status(0x52, b"\x00") == S.E_NO_PARAM_EXPECTED
    assert rig.value(0x52)["tag"] == "x" * 64


@pytest.mark.parametrize("model", ["wsg50", "wsg32", "wsg25", "wsg70"])
def test_system_limits(model: str) -> None:
    r = make_rig(model)
    v = r.value(0x53)
    p = r.g.profile
    assert v == pytest.approx(p.limits())
    assert r.status(0x53, b"\x00") == S.E_NO_PARAM_EXPECTED


def test_unknown_command(rig: Rig) -> None:
    reply = rig.call(0x90, b"")
    assert reply.encode() == bytes.fromhex("AAAAAA9002000E00FD02")  # manual 1.2.2 example 2


def test_homing_success_frame_matches_manual(rig: Rig) -> None:
    rig.status(0x20, direction=0)
    out = rig.run(5)
    assert out[0].encode() == bytes.fromhex("AAAAAA200200 0000 B3FD")


def test_preposition_frames_match_manual(homed: Rig) -> None:
    assert homed.call(0x21, flags=0, width=50.0, speed=50.0).encode() == bytes.fromhex("AAAAAA2102001A0067CB")
    assert homed.run(5)[0].encode() == bytes.fromhex("AAAAAA21020000002804")


def test_cmd_failure_flag_set_and_cleared(homed: Rig) -> None:
    homed.status(0x21, b"")
    assert homed.flags() & SF.SF_CMD_FAILURE
    homed.status(0x30, acceleration=200.0)
    assert not homed.flags() & SF.SF_CMD_FAILURE


def test_every_catalog_command_is_implemented(rig: Rig) -> None:
    for cid in CATALOG:
        reply = rig.g.handle_frame(rig.g.open_session("web"), Frame(cid, b"\x00" * 300))
        assert reply[-1].status != S.E_CMD_UNKNOWN, hex(cid)
