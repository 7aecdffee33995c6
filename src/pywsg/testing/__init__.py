"""Test your own WSG client against a virtual gripper: pytest fixture, thread-hosted server, world
control and scenarios (docs/testing.md).

``pip install pywsg`` registers the pytest plugin (:mod:`pywsg.testing.plugin`, fixture ``wsg_sim``);
:class:`SimThread` serves a virtual gripper from a background thread for any other test runner.
"""

from pathlib import Path

from .host import LoopThread, SimThread, World
from .scenario import Scenario, ScenarioError, ScenarioRunner
from .world import ACTIONS, FAULT_KINDS, WorldError, apply, world_state

SAMPLE_SESSION = Path(__file__).resolve().parent / "samples" / "wsg-session.pcapng"
"""A recorded ``wsg`` session with a WSG 50 (home, move, width, an unknown ID: pcapng, as ``wsg proxy --pcap``
writes), shipped with the package: ``wsg_sim.assert_replays(SAMPLE_SESSION)`` works from any directory.
The same file as the repository's docs/examples/wsg-session.pcapng."""

__all__ = [
    "ACTIONS", "FAULT_KINDS", "SAMPLE_SESSION", "LoopThread", "Scenario", "ScenarioError", "ScenarioRunner",
    "SimThread", "World", "WorldError", "apply", "world_state",
]
