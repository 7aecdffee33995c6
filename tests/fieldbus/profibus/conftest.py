"""A virtual WSG with its PROFIBUS DP slave on a fresh pty; stopped (pty closed) at teardown."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from typing import Any

import pytest

from ...simthread import SimThread, started


@pytest.fixture
def pb_factory() -> Iterator[Callable[..., SimThread]]:
    yield from started(SimThread)


@pytest.fixture
def pb_sim(pb_factory: Callable[..., SimThread]) -> SimThread:
    return pb_factory(tcp_port=None, udp_port=None, profibus="pty")


def adapter(sim: SimThread) -> Any:
    return sim.g.profibus
