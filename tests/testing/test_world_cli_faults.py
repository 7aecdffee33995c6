"""The new world vocabulary from outside a running `wsg sim` (issue 27 items 1 and 2): `wsg world net`,
`fault ack|watchdog|unplugged`, `slip`, `disconnect`, and the same actions in a scenario file."""

from __future__ import annotations

import json
import time
from pathlib import Path

import pytest
from click.testing import CliRunner, Result

from pywsg.cli.main import cli
from pywsg.client import Gripper
from pywsg.errors import TimeoutError
from pywsg.protocol import SystemFlag
from pywsg.testing import SimThread

from .conftest import SimProc, wsg


def _world(*args: str) -> Result:
    """``wsg world ARGS`` in this process (the same command code; the test's first line runs the real
    `wsg` in a subprocess): a subprocess each would cost a Python start-up per line."""
    return CliRunner().invoke(cli, ["world", *args])


def test_wsg_world_switches_network_and_user_faults(sim_proc: type[SimProc]) -> None:
    sim = sim_proc()
    r = wsg("world", "--sim", sim.web, "net", "latency", "--ms", "120", "--jitter", "10")
    assert r.returncode == 0 and r.stdout.startswith("latency 120 ms ± 10 ms"), r.stderr + r.stdout
    with Gripper(sim.url, timeout=3.0) as g:
        t = time.monotonic()
        g.loop(b"slow")
        assert time.monotonic() - t >= 0.1
    assert "network      latency ms=120 jitter=10" in _world("--sim", sim.web, "state").output
    assert _world("--sim", sim.web, "net", "clear").exit_code == 0
    r = _world("--sim", sim.web, "net", "drop", "-p", "7")
    assert r.exit_code == 1 and "p: must be within 0..1" in r.output  # refused, one line, exit 1
    r = _world("--sim", sim.web, "--json", "fault", "ack", "on")
    assert "acknowledge refused" in json.loads(r.output)["state"]["faults"]
    r = _world("--sim", sim.web, "--json", "fault", "watchdog", "on", "--timeout", "30")
    assert "watchdog 30 s" in json.loads(r.output)["state"]["faults"]
    r = _world("--sim", sim.web, "slip")
    assert r.exit_code == 1 and "no part between the fingers" in r.output
    with Gripper(sim.url, timeout=3.0) as g:
        g.loop(b"hello")
        r = _world("--sim", sim.web, "disconnect")
        assert r.exit_code == 0 and "connections interrupted by the gripper" in r.output
    assert json.loads(_world("--sim", sim.web, "--json", "state").output)["fast_stop"] is True


def test_scenario_switches_network_faults_and_slips_the_part(tmp_path: Path) -> None:
    path = tmp_path / "flaky.toml"
    path.write_text(
        '[[event]]\nat = 1.0\ndo = "net"\nkind = "silent"\n\n'
        '[[event]]\nat = 2.0\ndo = "net"\nkind = "silent"\non = false\n\n'
        '[[event]]\nafter = "HOLDING"\ndo = "slip"\nduration = 0.5\n'
    )
    with SimThread(clock="manual", scenario=path, udp_port=None) as sim, Gripper(sim.url, timeout=0.2) as g:
        sim.world.advance(1.0)
        with pytest.raises(TimeoutError):
            g.temperature()  # silent from t = 1 s
        sim.world.advance(1.0)
        g.reconnect()  # forget the timed-out call's ghost (docs/testing.md)
        assert not g.system_state() & SystemFlag.SF_FAST_STOP
        m = g.home(wait=False)
        sim.world.advance(3.0)
        m.wait(5)
        sim.world.place_part(30.0)
        m = g.grip(30.0, speed=100, wait=False)
        sim.world.advance(3.0)  # HOLDING within it; the slip (0.5 s after HOLDING) too
        m.wait(5)
        assert sim.world.state()["gripper_state"] == "PART_LOST"
        texts = [text for _, text in sim.scenario_runners[0].log]
        assert any(t.startswith("gripper silent") for t in texts)
        assert any(t.startswith("part slipping out") for t in texts)


def test_wsg_sim_net_starts_with_a_network_fault(sim_proc: type[SimProc]) -> None:
    sim = sim_proc("--net", "latency:ms=150")
    with Gripper(sim.url, timeout=3.0) as g:
        t = time.monotonic()
        g.loop(b"slow")
        assert time.monotonic() - t >= 0.14
    state = json.loads(_world("--sim", sim.web, "--json", "state").output)
    assert state["net"] == {"latency": {"ms": 150.0, "jitter": 0.0}}
    done = CliRunner().invoke(cli, ["sim", "--net", "latency:rate=5", "--tcp-port", "0", "--udp-port", "off",
                                    "--serial", "off", "--web-port", "off"])
    assert done.exit_code == 2 and "rate: not a parameter of latency" in done.output
