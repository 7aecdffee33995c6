"""The pytest plugin as a user meets it (issue 14 item 1): a separate test file, no conftest, run by
pytest in a subprocess; the plugin comes from the installed ``pytest11`` entry point."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

USER_TESTS = '''
import socket
import pytest
from pymodbus.client import ModbusTcpClient
from pywsg.client import AsyncGripper, Gripper
from pywsg.protocol import GripperState

def test_blocking_grip_holds_the_part(wsg_sim):
    wsg_sim.world.place_part(22.0, stiffness=400)
    with Gripper(wsg_sim.url) as g:
        g.home()
        g.grip(22.0, speed=100)
        assert g.gripper_state() == GripperState.HOLDING
    assert wsg_sim.world.state()["gripper_state"] == "HOLDING"

def test_each_test_gets_a_fresh_gripper(wsg_sim):
    state = wsg_sim.world.state()
    assert state["part"] is None and state["statistics"] == [0, 0, 0]

async def test_async_client(wsg_sim):
    wsg_sim.world.block(40.0)
    async with AsyncGripper(wsg_sim.url) as g:
        await g.home()
        assert await g.gripper_state() == GripperState.IDLE
    assert wsg_sim.world.state()["blocked_at"] == 40.0

@pytest.mark.wsg_sim(model="wsg32")
def test_marker_picks_the_model(wsg_sim):
    assert wsg_sim.world.state()["model"] == "wsg32"

@pytest.mark.parametrize("wsg_sim", [{"model": "wsg25"}, {"model": "wsg70"}], indirect=True)
def test_parameter_picks_the_model(wsg_sim):
    assert wsg_sim.world.state()["model"] in ("wsg25", "wsg70")

@pytest.mark.wsg_sim(clock="manual")
def test_manual_clock_moves_only_when_advanced(wsg_sim):
    with Gripper(wsg_sim.udp_url) as g:
        g.home(wait=False)
        assert wsg_sim.world.state()["time"] == 0.0
        wsg_sim.world.advance(5.0)
        assert wsg_sim.world.state()["time"] == 5.0
        assert g.width() > 100.0

def test_modbus_and_serial(wsg_sim):
    with ModbusTcpClient("127.0.0.1", port=wsg_sim.modbus_port) as mb:
        assert not mb.read_input_registers(0, count=6, device_id=1).isError()
    assert wsg_sim.serial_url.startswith("serial://")
    with Gripper(wsg_sim.serial_url) as g:
        assert g.temperature() > 0

@pytest.mark.wsg_sim(settings={"crc_check": False})
def test_settings_by_marker(wsg_sim):
    with socket.create_connection(("127.0.0.1", int(wsg_sim.url.rsplit(":", 1)[1])), timeout=5) as s:
        s.sendall(bytes.fromhex("AAAAAA 43 03 00 00 00 00 0000"))  # wrong checksum, CRC check off
        reply = s.recv(64)
    assert reply[3] == 0x43 and reply[6:8] == b"\\x00\\x00"  # E_SUCCESS (000 §1.4.1: CRC evaluation disabled)

def test_a_ring_gripped_from_inside(wsg_sim):
    wsg_sim.world.place_part(40.0, inside=True)  # issue 24 item 7: outside unless inside=True
    with Gripper(wsg_sim.url) as g:
        g.home()
        g.move(10.0, speed=100)
        g.grip(40.0, speed=100)
        assert g.gripper_state() == GripperState.HOLDING
    assert wsg_sim.world.state()["part_inside"] is True

def test_faults_and_heat(wsg_sim):
    wsg_sim.world.fault("power", True)
    assert wsg_sim.world.state()["fast_stop"] is True
    wsg_sim.world.heat(20)
    assert wsg_sim.world.state()["temperature"] >= 50
'''


def test_user_suite_runs_with_the_installed_plugin(tmp_path: Path) -> None:
    (tmp_path / "test_cell.py").write_text(USER_TESTS)
    r = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-o", "asyncio_mode=auto",
         "test_cell.py"], cwd=tmp_path, capture_output=True, text=True, timeout=180,
    )
    assert r.returncode == 0, r.stdout + r.stderr
    assert "11 passed" in r.stdout


def _first_python_block(page: Path) -> str:
    text = page.read_text(encoding="utf-8")
    start = text.index("```python\n") + len("```python\n")
    return text[start:text.index("```", start)]


def test_the_docs_fixture_example_runs_under_pytest_in_both_asyncio_modes(tmp_path: Path) -> None:
    """docs/testing.md's first example is a test file: run it with pytest as a user would, with
    pytest-asyncio in its default strict mode (the example marks its async test) and in auto mode."""
    doc = Path(__file__).resolve().parents[2] / "docs" / "testing.md"
    (tmp_path / "test_from_docs.py").write_text(_first_python_block(doc))
    for mode in ("strict", "auto"):
        r = subprocess.run(
            [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-o", f"asyncio_mode={mode}",
             "test_from_docs.py"],
            cwd=tmp_path, capture_output=True, text=True, timeout=180,
        )
        assert r.returncode == 0, r.stdout + r.stderr
        assert "5 passed" in r.stdout and "skipped" not in r.stdout, r.stdout


def test_plugin_is_registered_through_the_entry_point() -> None:
    from importlib.metadata import entry_points

    eps = {ep.name: ep.value for ep in entry_points(group="pytest11")}
    assert eps.get("pywsg") == "pywsg.testing.plugin"
