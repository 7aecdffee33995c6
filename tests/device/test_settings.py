"""Settings: validation naming the field, atomic save, corrupt files never overwritten, profiles."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from pywsg.device import PROFILES, Settings, SettingsError, VirtualGripper, decode_fw_version, get_profile
from pywsg.device.profiles import ASSUMED, DATA_SHEET
from pywsg.protocol import GripperState

from .devrig import make_rig


def test_defaults_and_roundtrip(tmp_path: Path) -> None:
    s = Settings(crc_check=False, homing_direction=2, clamping_travel=8.0, default_force_limit=40.0,
                 model="wsg32", finger1="fmf", script="ros_measure")
    path = tmp_path / "sub" / "settings.json"
    s.save(path)
    assert Settings.load(path) == s
    assert [p.name for p in path.parent.iterdir()] == ["settings.json"]  # no temporary left behind
    assert Settings.load(tmp_path / "missing.json") == Settings()


@pytest.mark.parametrize(("field", "value"), [
    ("crc_check", 1), ("homing_direction", 0), ("homing_direction", 3), ("clamping_travel", -1.0),
    ("clamping_travel", 1000.0), ("default_acceleration", 1.0), ("default_force_limit", 500.0),
    ("model", "wsg99"), ("finger1", "magic"), ("script", "nope"), ("serial_number", -5),
])
def test_validation_names_the_field(field: str, value: object) -> None:
    with pytest.raises(ValueError, match=field):
        Settings(**{field: value})  # type: ignore[arg-type]


def test_corrupt_file_is_a_clear_error_and_left_untouched(tmp_path: Path) -> None:
    path = tmp_path / "settings.json"
    path.write_text("{not json")
    with pytest.raises(SettingsError, match="corrupt"):
        Settings.load(path)
    assert path.read_text() == "{not json"
    path.write_text(json.dumps({"clamping_travel": "far"}))
    with pytest.raises(SettingsError, match="clamping_travel"):
        Settings.load(path)
    path.write_text(json.dumps({"colour": "red"}))
    with pytest.raises(SettingsError, match="colour"):
        Settings.load(path)
    path.write_bytes(b"\xff\xfe\x00")
    with pytest.raises(SettingsError, match="cannot read"):
        Settings.load(path)


def test_unreadable_file(tmp_path: Path) -> None:
    # a directory where the file should be: unreadable for everyone, root included (tests run as root)
    path = tmp_path / "settings.json"
    path.mkdir()
    with pytest.raises(SettingsError, match="cannot read"):
        Settings.load(path)
    assert path.is_dir()  # never silently replaced


def test_session_values_reset_on_restart() -> None:
    r = make_rig(settings=Settings(default_acceleration=300.0, default_force_limit=50.0))
    assert r.value(0x31)["acceleration"] == 300.0 and r.value(0x33)["force"] == 50.0
    r.status(0x30, acceleration=1000.0)
    r.status(0x32, force=20.0)
    r.status(0x34, minus=5.0, plus=100.0)
    r.home()
    r.g.restart()
    assert r.value(0x31)["acceleration"] == 300.0 and r.value(0x33)["force"] == 50.0
    assert r.status(0x35) == 1  # E_NOT_AVAILABLE: soft limits gone
    assert not r.g.referenced


def test_apply_settings_changes_model() -> None:
    r = make_rig()
    r.g.apply_settings(Settings(model="wsg25"))
    assert r.value(0x53)["stroke"] == get_profile("wsg25").stroke
    with pytest.raises(ValueError, match="model"):
        bad = Settings()
        object.__setattr__(bad, "model", "wsg99")  # bypassing the constructor's check
        r.g.apply_settings(bad)


def test_profiles_table_names_sources() -> None:
    assert set(PROFILES) == {"wsg50", "wsg32", "wsg25", "wsg70"}
    for p in PROFILES.values():
        for name in ("stroke", "max_speed", "nom_force", "ovr_force", "min_force", "max_acc"):
            assert p.sources[name].startswith((DATA_SHEET, ASSUMED, "command manual")), (p.key, name)
        assert decode_fw_version(p.fw_version) == (4, 0, 2, 0)
        assert p.min_speed < p.max_speed and p.min_force < p.nom_force <= p.ovr_force
    assert get_profile("WSG 50") is PROFILES["wsg50"]
    assert VirtualGripper().profile.key == "wsg50"
    with pytest.raises(ValueError, match="unknown device model"):
        get_profile("wsg99")


def test_auto_homing_at_power_up() -> None:
    r = make_rig(settings=Settings(auto_homing=True, homing_direction=2))
    assert r.g.snapshot().gripper_state == GripperState.POSITIONING  # homing runs without a command
    r.run(5)
    snap = r.g.snapshot()
    assert snap.referenced and snap.gripper_state == GripperState.IDLE
    assert abs(snap.width) < 1e-6  # negative direction: closed end stop
    assert any("auto-homing" in e.message for e in r.g.log)
    # a restart homes again; without the setting nothing moves
    r.g.restart()
    assert r.g.snapshot().gripper_state == GripperState.POSITIONING
    plain = make_rig()
    plain.run(5)
    assert not plain.g.snapshot().referenced
    with pytest.raises(SettingsError, match="auto_homing"):
        Settings(auto_homing="yes")  # type: ignore[arg-type]
