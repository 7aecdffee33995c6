"""Fixtures for the virtual gripper tests."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from .devrig import Rig, make_rig


@pytest.fixture
def rig() -> Iterator[Rig]:
    yield make_rig()


@pytest.fixture
def homed(rig: Rig) -> Rig:
    rig.home()
    return rig
