"""Firmware plugins: the ROS and UMI cmd_measure.lua emulations, the IF/OF hook, E_CMD_UNKNOWN."""

from __future__ import annotations

import math
import struct

import pytest

from pywsg.device import FirmwarePlugin, Settings, VirtualGripper
from pywsg.protocol import Frame, Status, SystemFlag

from .devrig import Rig, make_rig

S = Status


def test_script_commands_unknown_without_plugin(rig: Rig) -> None:
    for cid in (0xB0, 0xB1, 0xB2):
        assert rig.status(cid, bytes(9)) == S.E_CMD_UNKNOWN
    assert not rig.flags() & SystemFlag.SF_SCRIPT_RUNNING


def test_ros_measure(homed: Rig) -> None:
    homed.g.load_plugin("ros_measure")
    assert homed.flags() & SystemFlag.SF_SCRIPT_RUNNING
    reply = homed.call(0xB0, bytes(9))
    assert reply.status == S.E_SUCCESS and len(reply.params) == 21
    state, w, v, f, f0, f1 = struct.unpack("<B5f", reply.params)
    assert state == int(homed.g.system_flags()) & 0xFF
    assert w == 110.0 and v == 0.0 and f == 0.0 and math.isnan(f0) and math.isnan(f1)
    # B1h position control
    homed.call(0xB1, struct.pack("<Bff", 0, 50.0, 100.0))
    homed.run(5)
    assert abs(homed.g.width() - 50.0) < 1e-6
    # B2h speed control: closes until blocked, then the script stops
    homed.g.faults.block_at(20.0)
    homed.call(0xB2, struct.pack("<Bff", 0, 0.0, -30.0))
    homed.clock.advance(0.5)
    _, w, v, *_ = struct.unpack("<B5f", homed.call(0xB0, bytes(9)).params)
    assert v == pytest.approx(-30.0) and w < 50.0
    homed.run(5)
    _, w, v, *_ = struct.unpack("<B5f", homed.call(0xB0, bytes(9)).params)
    assert w == pytest.approx(20.0) and v == 0.0
    assert homed.status(0xB1, b"\x00") == S.E_CMD_FORMAT_ERROR
    homed.g.unload_plugin("ros_measure")
    assert homed.status(0xB0, bytes(9)) == S.E_CMD_UNKNOWN
    assert not homed.flags() & SystemFlag.SF_SCRIPT_RUNNING


def test_ros_measure_reports_fmf_forces() -> None:
    r = make_rig(settings=Settings(finger1="fmf", script="ros_measure"))
    _, _, _, _, f0, f1 = struct.unpack("<B5f", r.call(0xB0, bytes(9)).params)
    assert f0 == pytest.approx(0.2) and math.isnan(f1)


def test_umi_pd_control_tracks_position(homed: Rig) -> None:
    homed.g.load_plugin("umi_measure")
    target = 40.0
    for _ in range(300):  # 30 Hz control loop for 10 s
        req = struct.pack("<B6f", 0, target, 0.0, 5.0, 0.0, 20.0, 40.0)
        reply = homed.call(0xB1, req)
        assert reply.status == S.E_SUCCESS and len(reply.params) == 17
        homed.clock.advance(1 / 30)
    state, pos, vel, _force, t = struct.unpack("<B4f", homed.call(0xB0, b"").params)
    assert pos == pytest.approx(target, abs=0.5) and abs(vel) < 1.0
    assert t == pytest.approx(homed.clock.now, rel=1e-6)
    assert state == int(homed.g.system_flags()) & 0xFF


def test_umi_blocked_force_limit(homed: Rig) -> None:
    homed.g.load_plugin("umi_measure")
    homed.g.faults.block_at(30.0)
    for _ in range(200):
        homed.call(0xB1, struct.pack("<B6f", 0, 0.0, 0.0, 10.0, 0.0, 20.0, 45.0))
        homed.clock.advance(1 / 30)
    _, pos, _vel, force, _ = struct.unpack("<B4f", homed.call(0xB0, b"").params)
    assert pos == pytest.approx(30.0) and force == pytest.approx(45.0)
    assert homed.g.blocked()


def test_plugin_cannot_take_manual_ids() -> None:
    class Bad(FirmwarePlugin):
        name = "bad"
        commands = (0x20,)

    g = VirtualGripper()
    with pytest.raises(ValueError, match="20h"):
        g.load_plugin(Bad())


def test_custom_plugin_and_if_of_mirror(rig: Rig) -> None:
    class Echo(FirmwarePlugin):
        name = "echo"
        commands = (0xC0,)

        def handle(self, gripper: VirtualGripper, session: object, command_id: int, payload: bytes,
                   now: float) -> Frame:
            return Frame.reply(command_id, S.E_SUCCESS, payload[::-1])

    rig.g.load_plugin(Echo())
    assert rig.call(0xC0, b"abc").params == b"cba"
    rig.g.load_plugin("if_of_mirror")
    rig.g.set_script_if(0x1234)
    assert rig.g.snapshot().script_of == 0x1234


class _Crashing(FirmwarePlugin):
    """A script with a bug: C1h divides by zero, an IF change of 0xDEAD indexes past a list."""

    name = "crashing"
    commands = (0xC1, 0xC2)

    def handle(self, gripper: VirtualGripper, session: object, command_id: int, payload: bytes,
               now: float) -> Frame:
        if command_id == 0xC1:
            return Frame.reply(command_id, S.E_SUCCESS, bytes([1 // len(payload)]))
        return Frame.reply(command_id, S.E_SUCCESS)

    def on_if_changed(self, gripper: VirtualGripper, value: int) -> None:
        if value == 0xDEAD:
            [][0]


def test_a_script_error_aborts_the_script_and_sets_script_failure(rig: Rig) -> None:
    """000 App. B (D20 SF_SCRIPT_FAILURE): "An error occurred while executing a script and the script has been
    aborted. The flag is reset whenever a script is started." """
    rig.g.load_plugin(_Crashing())
    assert rig.status(0xC1, b"x") == S.E_SUCCESS
    assert rig.status(0xC1, b"") == S.E_CMD_FAILED  # the request that hit the error
    flags = SystemFlag(rig.flags())
    assert flags & SystemFlag.SF_SCRIPT_FAILURE and not flags & SystemFlag.SF_SCRIPT_RUNNING
    assert rig.status(0xC2) == S.E_CMD_UNKNOWN  # aborted: its command IDs are gone
    assert any(m.startswith("script crashing aborted: ZeroDivisionError") for m in rig.g.log.messages())
    rig.g.load_plugin("if_of_mirror")  # starting a script resets the flag
    assert not SystemFlag(rig.flags()) & SystemFlag.SF_SCRIPT_FAILURE
    rig.g.load_plugin(_Crashing())
    rig.g.set_script_if(0xDEAD)  # an error in the IF hook aborts only that script
    assert SystemFlag(rig.flags()) & SystemFlag.SF_SCRIPT_FAILURE
    assert list(rig.g.snapshot().plugins) == ["if_of_mirror"] and rig.g.snapshot().script_of == 0xDEAD
