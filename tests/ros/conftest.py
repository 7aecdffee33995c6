"""Fixtures of the ROS tests: one rig (sim, node process, client process) per module, shared by its tests."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest

from .rig import Rig, shm_left_behind, skip_reason, wait_until


def open_rig(tmp: Path, **kw: object) -> Iterator[Rig]:
    """Body of a module's ``rig`` fixture: started, and at the end stopped with the checks every module
    shares: the node exits 0 on SIGTERM, the gripper is left without FAST STOP (released with its
    disconnect announcement), no process and no Fast DDS shared-memory file is left."""
    reason = skip_reason()
    if reason is not None:
        pytest.skip(reason)
    rig = Rig(tmp, **kw).start()  # type: ignore[arg-type]
    node, client = rig.node, rig.client
    try:
        yield rig
    finally:
        status = rig.close()
    assert status == 0, rig.log_tail()
    assert node is not None and node.poll() is not None and client is not None and client.poll() is not None
    assert not rig.world_after["fast_stop"], "the node left without announcing its disconnect (07h)"
    # Fast DDS removes its segments when a participant closes: none may outlive our processes
    assert wait_until(lambda: not shm_left_behind(rig.shm_before), timeout=5), shm_left_behind(rig.shm_before)


def rig_fixture(name: str, **kw: Any) -> Callable[..., Iterator[Rig]]:
    """A module-scoped ``rig`` fixture (one node process per module, shared by its tests):
    ``rig = rig_fixture("ros-action")`` in the module."""

    @pytest.fixture(scope="module")
    def rig(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Rig]:
        yield from open_rig(tmp_path_factory.mktemp(name), **kw)

    return rig
