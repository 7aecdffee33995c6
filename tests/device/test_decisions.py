"""Where the manuals leave it open: the decisions of docs/fidelity.md (issue 24 items 5 and 6), one test
each, in raw frames on the manual clock."""

from __future__ import annotations

import struct

import pytest

from pywsg.device import ManualClock, Session, Settings, VirtualGripper
from pywsg.protocol import Frame, GripperState, Status, SystemFlag

from .devrig import Rig, make_rig

S = Status
GS = GripperState
SF = SystemFlag


def _raw(rig: Rig, cid: int, payload: bytes) -> Status | int:
    (reply,) = rig.g.feed(rig.s, Frame(cid, payload).encode())
    return reply.status


def _finals(rig: Rig, cid: int, dt: float = 5.0) -> list[int]:
    return [int(f.status) for f in rig.run(dt) if f.command_id == cid]


def test_a_homing_stopped_by_22h_leaves_the_gripper_unreferenced(homed: Rig) -> None:
    """000 §3.2.1: homing gives up the old origin when it starts (SF_REFERENCED clears) and finds the
    new one at the end stop; stopped by 22h (E_CMD_ABORTED) it found none: 21h → E_NOT_INITIALIZED."""
    assert homed.flags() & SF.SF_REFERENCED
    assert _raw(homed, 0x20, b"\x02") == S.E_CMD_PENDING
    assert not homed.flags() & SF.SF_REFERENCED
    homed.run(0.05)
    replies = homed.g.feed(homed.s, Frame(0x22, b"").encode())
    assert [(f.command_id, f.status) for f in replies] == [(0x20, S.E_CMD_ABORTED), (0x22, S.E_SUCCESS)]
    assert not homed.flags() & SF.SF_REFERENCED
    assert _raw(homed, 0x21, struct.pack("<Bff", 0, 50.0, 50.0)) == S.E_NOT_INITIALIZED
    assert _raw(homed, 0x20, b"\x01") == S.E_CMD_PENDING
    assert _finals(homed, 0x20) == [S.E_SUCCESS] and homed.flags() & SF.SF_REFERENCED


def test_an_unannounced_close_without_fast_stop_lets_the_motion_finish() -> None:
    """000 §1.4.2 with the disconnect error state switched off: closing the TCP connection during a 21h
    is no event for the motion; it arrives (41h IDLE, no FAST STOP) and its final reply is dropped."""
    rig = make_rig(settings=Settings(fast_stop_on_disconnect=False))
    rig.home()
    assert _raw(rig, 0x21, struct.pack("<Bff", 0, 20.0, 50.0)) == S.E_CMD_PENDING
    rig.g.close_session(rig.s)
    assert rig.g.moving()
    rig.clock.advance(5.0)
    assert [f for _, f in rig.g.poll()] == []  # nobody to send the 21h's final reply to
    snap = rig.g.snapshot()
    assert snap.width == 20.0 and snap.gripper_state == GS.IDLE and not snap.fast_stop


def test_stop_while_holding_keeps_the_part(rig: Rig) -> None:
    """000 §3.2.3 Stop "stops any ongoing finger movement"; holding is none: 22h while HOLDING answers
    E_SUCCESS, sets SF_AXIS_STOPPED, and the part stays held with its force (002 §4.5's STOP/ACK, which
    lets go, is the fieldbus's own command)."""
    rig.home()
    rig.g.faults.place_part(30.0)
    _raw(rig, 0x25, struct.pack("<ff", 30.0, 50.0))
    assert _finals(rig, 0x25) == [S.E_SUCCESS]
    assert _raw(rig, 0x22, b"") == S.E_SUCCESS
    assert rig.gstate() == GS.HOLDING and rig.flags() & SF.SF_AXIS_STOPPED
    assert float(rig.value(0x45, flags=0, period_ms=0)["force"]) == 80.0  # type: ignore[arg-type]


def test_release_to_a_smaller_width_moves_there(homed: Rig) -> None:
    """000 §3.2.7 OPENWIDTH is an "absolute target position": from IDLE at 110 mm, 26h to 20 mm closes
    the fingers to 20 mm (RELEASING, then IDLE, E_SUCCESS)."""
    assert _raw(homed, 0x26, struct.pack("<ff", 20.0, 50.0)) == S.E_CMD_PENDING
    assert homed.gstate() == GS.RELEASING
    assert _finals(homed, 0x26) == [S.E_SUCCESS]
    assert homed.width() == 20.0 and homed.gstate() == GS.IDLE


def test_soft_limits_are_returned_as_set(homed: Rig) -> None:
    """000 §3.3.6 35h "Return the soft limits if set": limits beyond the stroke come back as given
    (-5 and 200 mm, float32), never bite, and SF_SOFT_LIMIT_PLUS stays off at 110 mm."""
    assert _raw(homed, 0x34, struct.pack("<ff", -5.0, 200.0)) == S.E_SUCCESS
    (reply,) = homed.g.feed(homed.s, Frame(0x35, b"").encode())
    assert reply.payload == b"\x00\x00" + struct.pack("<ff", -5.0, 200.0)
    assert not homed.flags() & (SF.SF_SOFT_LIMIT_PLUS | SF.SF_SOFT_LIMIT_MINUS)
    _raw(homed, 0x21, struct.pack("<Bff", 0, 0.0, 100.0))
    assert _finals(homed, 0x21) == [S.E_SUCCESS] and homed.width() == 0.0
    assert _raw(homed, 0x34, struct.pack("<ff", 5.0, 100.0)) == S.E_SUCCESS
    assert homed.flags() & SF.SF_SOFT_LIMIT_MINUS  # inside the restricted area: the flag (000 §3.3.5 NOTE)


def test_motion_during_a_temperature_fault_is_access_denied(homed: Rig) -> None:
    """App. B D14 SF_TEMP_FAULT: "All motion-related commands are disabled": each answers E_ACCESS_DENIED,
    the code §3.2.4 gives for prohibited motion commands."""
    homed.g.faults.heat(100.0)
    assert homed.flags() & SF.SF_TEMP_FAULT
    for cid, payload in ((0x20, b"\x00"), (0x21, struct.pack("<Bff", 0, 50.0, 50.0)),
                         (0x25, struct.pack("<ff", 50.0, 50.0)), (0x26, struct.pack("<ff", 50.0, 50.0))):
        assert _raw(homed, cid, payload) == S.E_ACCESS_DENIED, f"{cid:02X}h"
    assert homed.g.jog(-1, 10.0, 20.0) == S.E_ACCESS_DENIED


def test_a_refused_auto_update_request_leaves_the_running_stream(homed: Rig) -> None:
    """000 §3.4.4 43h: PERIOD_MS "Minimum value is 10 ms". A stream at 100 ms runs; a second request
    with 5 ms is refused (E_INVALID_PARAMETER) and the stream goes on at 100 ms: 10 updates a second."""
    assert _raw(homed, 0x43, b"\x01" + struct.pack("<H", 100)) == S.E_SUCCESS
    assert _raw(homed, 0x43, b"\x01" + struct.pack("<H", 5)) == S.E_INVALID_PARAMETER
    updates = [f for f in homed.run(1.0) if f.command_id == 0x43]
    assert len(updates) == 10 and all(f.status == S.E_SUCCESS for f in updates)


@pytest.mark.parametrize("cid", [0x62, 0x72])
def test_finger_power_on_off_is_byte_0(rig: Rig, cid: int) -> None:
    """Misprint: 000 §3.6.3 puts 62h's ON/OFF in "Byte 1"; 72h (§3.6.7) and 001 put it in byte 0, the
    request's only byte. One byte 00h switches the generic finger off; two bytes are a length error."""
    assert _raw(rig, cid, b"\x00") == S.E_SUCCESS
    assert not rig.g.fingers[cid // 0x10 - 6].powered
    assert _raw(rig, cid, b"\x01\x00") == S.E_CMD_FORMAT_ERROR


# ---------------------------------------------------------------- item 6: the default acceleration

def _umi_loop(g: VirtualGripper, s: Session, clock: ManualClock, target: float) -> tuple[float, float]:
    """Stanford UMI's ``WSGController.run`` (umi/real_world/wsg_controller.py), unchanged in substance:
    30 Hz, ``script_position_pd(position, velocity)`` with its defaults kp 15, kd 1e-3, force 80 N,
    the target interpolated from the current width at UMI's ``move_max_speed`` 200 mm/s. Returns the
    lowest width and the final width."""
    dt = 1 / 30
    start = g.width()
    t_move = abs(start - target) / 200.0

    def interp(t: float) -> float:
        return start + (target - start) * min(max(t / t_move, 0.0), 1.0)

    widths = []
    for i in range(int(3.0 / dt)):
        pos = interp(i * dt)
        vel = (pos - interp(i * dt - dt)) / dt
        (reply,) = g.handle_frame(s, Frame(0xB1, struct.pack("<B6f", 0, pos, vel, 15.0, 1e-3, 80.0, 80.0)))
        assert reply.status == S.E_SUCCESS
        widths.append(struct.unpack_from("<B4f", reply.params)[1])
        clock.advance(dt)
        g.poll()
    return min(widths), widths[-1]


def test_umi_30hz_pd_loop_tracks_with_the_default_acceleration() -> None:
    """docs/fidelity.md "Default acceleration": UMI never sends 30h, so it runs at the gripper's default.
    With pywsg's default (5000 mm/s², 31h) its loop reaches 80 mm from the open fingers without
    overshooting; with the manual's example value 150 mm/s² the same loop overshoots by over 10 mm."""
    clock = ManualClock()
    g = VirtualGripper("wsg50", clock=clock)
    s = g.open_session("tcp")
    (reply,) = g.handle_frame(s, Frame(0x31, b""))
    assert reply.payload == b"\x00\x00" + struct.pack("<f", 5000.0)
    g.handle_frame(s, Frame(0x20, b"\x01"))  # UMI: homing(positive_direction=True)
    clock.advance(5.0)
    g.poll()
    g.load_plugin("umi_measure")
    lowest, final = _umi_loop(g, s, clock, 80.0)
    assert lowest >= 80.0 - 0.05 and final == pytest.approx(80.0, abs=0.05)

    clock = ManualClock()
    slow = VirtualGripper("wsg50", settings=Settings(default_acceleration=150.0), clock=clock)
    s = slow.open_session("tcp")
    slow.handle_frame(s, Frame(0x20, b"\x01"))
    clock.advance(5.0)
    slow.poll()
    slow.load_plugin("umi_measure")
    lowest, _ = _umi_loop(slow, s, clock, 80.0)
    assert lowest < 70.0  # the overshoot the audit saw
