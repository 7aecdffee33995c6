"""Test your own WSG client against a virtual gripper: pytest fixture, thread-hosted server, world
control and scenarios (docs/testing.md).

``pip install pywsg`` registers the pytest plugin (:mod:`pywsg.testing.plugin`, fixture ``wsg_sim``);
:class:`SimThread` serves a virtual gripper from a background thread for any other test runner.
"""

from .host import LoopThread, SimThread, World
from .scenario import Scenario, ScenarioError, ScenarioRunner
from .world import ACTIONS, FAULT_KINDS, WorldError, apply, world_state

__all__ = [
    "ACTIONS", "FAULT_KINDS", "LoopThread", "Scenario", "ScenarioError", "ScenarioRunner", "SimThread", "World",
    "WorldError", "apply", "world_state",
]
