"""Scenarios (issue 14 item 3): world events at absolute times and relative to commands and gripper
states, deterministic on the manual clock; and `wsg sim --scenario` as a subprocess."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from pywsg.client import Gripper
from pywsg.errors import WsgError
from pywsg.protocol import GripperState
from pywsg.testing import Scenario, ScenarioError, SimThread

from .conftest import SimProc, wsg

DOCS = Path(__file__).resolve().parents[2] / "docs" / "scenarios"


def _write(tmp_path: Path, text: str) -> Path:
    p = tmp_path / "s.toml"
    p.write_text(text)
    return p


def _cycle(sim: SimThread, g: Gripper) -> GripperState:
    """Grip at 22 mm and let the manual clock run until the grip is over (000 §3.2.6)."""
    g.grip(22.0, speed=100, wait=False)
    sim.world.advance(2.0)
    state = GripperState[sim.world.state()["gripper_state"]]
    g.release(60.0, speed=200, wait=False)
    sim.world.advance(2.0)
    return state


def run_story(path: Path) -> list[tuple[float, str]]:
    with SimThread(clock="manual", scenario=path, udp_port=0, tcp_port=None) as sim, Gripper(sim.udp_url) as g:
        g.home(wait=False)
        sim.world.advance(3.0)
        states = [_cycle(sim, g) for _ in range(3)]
        assert states == [GripperState.HOLDING, GripperState.HOLDING, GripperState.PART_LOST]
        return list(sim.scenario_runners[0].log)


def test_lost_part_story_is_the_same_every_time() -> None:
    path = DOCS / "lost-part.toml"
    first = run_story(path)
    assert first == run_story(path)  # deterministic on the manual clock
    removed = [t for t, text in first if text.startswith("part removed")]
    placed = [t for t, text in first if text.startswith("part of 22 mm placed")]
    assert len(placed) == 3 and len(removed) == 1
    # "0.5 s after HOLDING on the 3rd cycle": holding began at the contact, before the removal
    assert removed[0] > placed[2] + 0.5


def test_absolute_time_power_fault_and_recovery() -> None:
    path = DOCS / "fast-stop-recovery.toml"
    with SimThread(clock="manual", scenario=path, tcp_port=None) as sim, Gripper(sim.udp_url) as g:
        sim.world.advance(4.999)
        assert sim.world.state()["fast_stop"] is False
        sim.world.advance(0.001)
        state = sim.world.state()
        assert state["fast_stop"] is True and "power" in state["faults"]  # 000 Appendix B SF_POWER_FAULT
        with pytest.raises(WsgError):  # 000 §3.2.5: no acknowledge while the fault persists
            g.acknowledge()
        sim.world.advance(2.0)
        assert "power" not in sim.world.state()["faults"]
        g.acknowledge()
        assert sim.world.state()["fast_stop"] is False


def test_before_command_places_the_part_for_every_grip(tmp_path: Path) -> None:
    path = DOCS / "scl-demo-with-part.toml"
    with SimThread(clock="manual", scenario=path, tcp_port=None) as sim, Gripper(sim.udp_url) as g:
        g.home(wait=False)
        sim.world.advance(3.0)
        for _ in range(2):
            assert _cycle(sim, g) == GripperState.HOLDING
            sim.world.remove_part()  # taken away after each release: the scenario brings the next one


@pytest.mark.parametrize(("text", "message"), [
    ('[[event]]\nat = 1\ndo = "explode"\n', "do: must be one of"),
    ('[[event]]\ndo = "part"\nwidth = 1\n', "exactly one of at / before / after"),
    ('[[event]]\nbefore = "NOPE"\ndo = "unblock"\n', "unknown command 'NOPE'"),
    ('[[event]]\nafter = "FLYING"\ndo = "unblock"\n', "must be a gripper state"),
    ('[[event]]\nafter = "HOLDING"\ncycle = 0\ndo = "unblock"\n', "cycle: must be a whole number"),
    ("[[event]\n", "not valid TOML"),
])
def test_bad_scenarios_name_the_event_and_key(tmp_path: Path, text: str, message: str) -> None:
    with pytest.raises(ScenarioError, match=message):
        Scenario.load(_write(tmp_path, text))


def test_wsg_sim_scenario_runs_in_real_time(tmp_path: Path, sim_proc: type[SimProc]) -> None:
    path = _write(tmp_path, '[[event]]\nat = 0.2\ndo = "part"\nwidth = 30\n\n'
                            '[[event]]\nbefore = "HOMING"\ndo = "heat"\ndelta_c = 10\n')
    sim = sim_proc("--scenario", str(path))
    sim.wait_for("part of 30 mm placed")
    assert wsg("--url", sim.url, "home").returncode == 0
    sim.wait_for("temperature changed by +10")
    r = wsg("sim", "--scenario", str(_write(tmp_path, "[[event]]\nat = -1\ndo = 'unblock'\n")))
    assert r.returncode == 2 and "non-negative" in r.stderr


def test_plc_demo_loses_the_part_in_cycle_3(sim_proc: type[SimProc]) -> None:
    """The docs' example: the SCL demo cycle (002 Appendix D) against `wsg sim --scenario lost-part.toml`."""
    sim = sim_proc("--scenario", str(DOCS / "lost-part.toml"), modbus=True)
    r = wsg("plc-demo", "--url", f"modbus-tcp://127.0.0.1:{sim.modbus_port}", "--cycles", "3", timeout=90)
    assert r.returncode == 0, r.stdout + r.stderr
    # 002 App. D step 7 "No part found or part lost. Go to next step": the listing releases and goes on
    # on its normal path (issue 24 item 2), no FAST STOP from a parameter change while the fingers move
    assert "step  7 ->  8: release: wait for RELEASING, reset RELEASE  [PART_LOST, E_SUCCESS]" in r.stdout
    done = r.stdout.strip().splitlines()[-1]
    assert done == "done: 3 cycles, 3 parts held, 0 without part, 0 error recoveries", done
    sim.wait_for("part removed (remove_part 0.5 s after HOLDING (occurrence 3))")



def test_wsg_sim_json_reports_scenario_actions_as_json(tmp_path: Path, sim_proc: type[SimProc]) -> None:
    path = _write(tmp_path, '[[event]]\nat = 0.1\ndo = "block"\nwidth = 30\n')
    sim = sim_proc("--json", "--scenario", str(path))
    line = sim.wait_for('"event": "scenario"')
    event = json.loads(line)
    assert event["gripper"] == 0 and event["action"].startswith("fingers blocked at 30 mm") and event["t"] >= 0.1


def test_plc_demo_recovers_from_the_scenario_fast_stop(sim_proc: type[SimProc]) -> None:
    """The docs' example: a 2 s power fault at t = 5 s (FAST STOP, 000 App. B SF_POWER_FAULT) in
    whatever step it catches the SCL cycle (002 App. D); it acknowledges, homes and finishes."""
    sim = sim_proc("--part", "22", "--scenario", str(DOCS / "fast-stop-recovery.toml"), modbus=True)
    r = wsg("plc-demo", "--url", f"modbus-tcp://127.0.0.1:{sim.modbus_port}", "--cycles", "6", "--timeout", "50",
            "--recover-fast-stop", timeout=90)
    assert r.returncode == 0, r.stdout + r.stderr
    sim.wait_for("power")  # the fault did strike during the run (t = 5 s; six cycles take about 9 s)
    done = r.stdout.strip().splitlines()[-1]
    assert done.startswith("done: 6 cycles") and "timed out" not in done, r.stdout[-3000:]
    recoveries = re.search(r"(\d+) error recover(?:y|ies)", done)
    assert recoveries is not None and int(recoveries.group(1)) > 0, done  # "270 …" contains "0 error recoveries"
