"""A faster-than-real clock, a cell of grippers and recordings as regression tests (issue 27 items 3-5)."""

from __future__ import annotations

import json
import subprocess
import time
from pathlib import Path

import pytest

from pywsg.client import Gripper
from pywsg.device import ManualClock, ScaledClock
from pywsg.protocol import GripperState
from pywsg.testing import SimThread

from .conftest import ENV, WSG

SAMPLE = Path(__file__).resolve().parents[2] / "docs" / "examples" / "wsg-session.pcapng"


# -- time scale -------------------------------------------------------------------------------------

def test_scaled_clock_runs_k_times_real_time() -> None:
    clock = ScaledClock(50.0)
    t0, r0 = clock(), time.monotonic()
    time.sleep(0.05)
    dt, real = clock() - t0, time.monotonic() - r0
    assert dt == pytest.approx(real * 50.0, rel=0.05)  # the ratio, measured against the same sleep
    with pytest.raises(ValueError, match="positive"):
        ScaledClock(0)


def test_time_scale_homes_k_times_sooner_with_the_same_device_duration() -> None:
    """The homing takes the same time on the gripper's clock; with K = 25 the wall clock sees 1/25 of it."""
    with SimThread(clock="manual") as sim, Gripper(sim.url) as g:
        m = g.home(wait=False)
        start = sim.clock.now  # type: ignore[union-attr]
        while sim.world.state()["width"] < 109.99 and sim.clock.now - start < 30:  # type: ignore[union-attr]
            sim.world.advance(0.01)
        device_duration = sim.clock.now - start  # type: ignore[union-attr]
        m.wait(5)
    assert device_duration > 0.5  # a real homing stroke, not an instant
    with SimThread(time_scale=25) as sim, Gripper(sim.url, timeout=10) as g:
        assert isinstance(sim.options.clock, ScaledClock)
        r0 = time.monotonic()
        t0 = sim.options.clock()
        g.home()
        real, device = time.monotonic() - r0, sim.options.clock() - t0
    # the same stroke on the gripper's clock (the reply's way back adds K times its real latency)
    assert device >= device_duration * 0.99
    assert real < device_duration  # K = 25: 1/25 of it plus the machine's latency (generous under load)


def test_time_scale_cools_the_motor_k_times_sooner() -> None:
    """The thermal model (tau 300 s) on a 1000x clock: a minute of cooling in well under a second."""
    with SimThread(time_scale=1000) as sim:
        sim.world.heat(40.0)
        hot = sim.world.state()
        deadline = time.monotonic() + 10
        while sim.world.state()["time"] - hot["time"] < 60 and time.monotonic() < deadline:
            time.sleep(0.01)
        cooled = sim.world.state()
    assert cooled["time"] - hot["time"] >= 60, "the scaled clock did not run"
    assert cooled["temperature"] < hot["temperature"] - 5  # 40 °C above equilibrium: ~7.3 °C per minute


def test_time_scale_and_clock_are_exclusive() -> None:
    with pytest.raises(ValueError, match="time_scale and clock"):
        SimThread(clock="manual", time_scale=10)
    with pytest.raises(ValueError, match="time_scale: must be a positive number"):
        SimThread(time_scale=-1)


def test_time_scale_runs_a_scenario_sooner(tmp_path: Path) -> None:
    path = tmp_path / "late.toml"
    path.write_text('[[event]]\nat = 20.0\ndo = "heat"\ndelta_c = 30\n')
    with SimThread(time_scale=100, scenario=path) as sim:
        deadline = time.monotonic() + 10  # 20 s of scenario time: 0.2 s of real time at K = 100
        while not sim.scenario_runners[0].log and time.monotonic() < deadline:
            time.sleep(0.01)
        assert sim.scenario_runners[0].log, "the scenario event at t=20 s never ran at K=100"
        # it ran at t >= 20 s of scenario time, never early; how late depends on the machine's load
        # (1 ms of real delay is 0.1 s of scenario time at K = 100), so no upper bound here: running
        # within the 10 s of real time above, half the 20 s it takes at K = 1, is what shows the scaling
        assert sim.scenario_runners[0].log[0][0] >= 20.0 - 1e-6  # float rounding of now - start


# -- a cell -----------------------------------------------------------------------------------------

@pytest.mark.wsg_cell(count=2, clock="manual")
def test_cell_grippers_have_their_own_worlds_and_share_the_time(wsg_cell: SimThread) -> None:
    left, right = wsg_cell
    assert left.url != right.url
    left.world.place_part(22.0)
    right.world.block(40.0)
    assert left.world.state()["part"] == 22.0 and left.world.state()["blocked_at"] is None
    assert right.world.state()["part"] is None and right.world.state()["blocked_at"] == 40.0
    with Gripper(left.url) as a, Gripper(right.url) as b:
        ma, mb = a.home(wait=False), b.home(wait=False)
        left.world.advance(5.0)  # the shared manual clock: both grippers move on
        ma.wait(5)
        mb.wait(5)
        assert a.width() > 100 and b.width() > 100
    assert isinstance(wsg_cell.clock, ManualClock)
    assert right.world.state()["time"] == left.world.state()["time"] == 5.0


def test_sim_count_prints_every_grippers_urls_and_time_scale_speeds_them() -> None:
    proc = subprocess.Popen([*WSG, "sim", "--no-uvloop", "--json", "--count", "2", "--time-scale", "20",
                             "--tcp-port", "0", "--udp-port", "off", "--serial", "off", "--web-port", "off"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=ENV)
    try:
        assert proc.stdout is not None
        urls: dict[int, str] = {}
        while len(urls) < 2:
            line = proc.stdout.readline()
            assert line, f"wsg sim ended: {proc.stderr.read() if proc.stderr else ''}"
            event = json.loads(line)
            if event.get("kind") == "tcp":
                urls[event["gripper"]] = event["url"]
        assert urls[0] != urls[1]
        for url in urls.values():
            with Gripper(url, timeout=10) as g:
                g.home(timeout=10)  # ~1.2 s of gripper time, 60 ms at K = 20
                assert g.gripper_state() == GripperState.IDLE
    finally:
        proc.terminate()
        proc.communicate(timeout=15)


# -- record once, test forever ----------------------------------------------------------------------

@pytest.mark.wsg_sim(clock="manual")
def test_a_recorded_session_replays_in_one_line(wsg_sim: SimThread) -> None:
    report = wsg_sim.assert_replays(SAMPLE)
    assert report.steps >= 3 and report.replies >= report.steps


@pytest.mark.wsg_sim(clock="manual", model="wsg32")
def test_a_replay_that_differs_fails_with_every_difference_named(wsg_sim: SimThread) -> None:
    with pytest.raises(AssertionError, match=r"difference\(s\) from the recording") as err:
        wsg_sim.assert_replays(SAMPLE)  # recorded on a WSG 50 (110 mm stroke); this is a WSG 32
    assert "width: recorded 110 mm" in str(err.value)


def test_wsg_replay_sim_is_the_ci_one_liner() -> None:
    from .conftest import wsg

    done = wsg("replay", str(SAMPLE), "--sim", "wsg50")
    assert done.returncode == 0 and "all replies matched" in done.stdout, done.stdout + done.stderr
    from click.testing import CliRunner

    from pywsg.cli.main import cli

    res = CliRunner().invoke(cli, ["replay", str(SAMPLE), "--sim", "wsg32", "--json"])
    assert res.exit_code == 1
    report = json.loads(res.output)
    assert not report["matched"] and any(d["what"] == "width" for d in report["differences"])
    res = CliRunner().invoke(cli, ["replay", str(SAMPLE)])
    assert res.exit_code == 2 and "--to URL or --sim MODEL" in res.output
