"""The test suite's ``SimThread`` is the public :class:`pywsg.testing.SimThread`; ``started`` is the
body of the ``sim_factory`` fixtures."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from typing import Any, TypeVar

from pywsg.testing import SimThread

S = TypeVar("S", bound=SimThread)

__all__ = ["SimThread", "started"]


def started(cls: type[S]) -> Iterator[Callable[..., S]]:
    """Body of a ``sim_factory`` fixture: ``make(**options)`` starts one; all stop at teardown."""
    running: list[S] = []

    def make(**options: Any) -> S:
        st = cls(**options).start()
        running.append(st)
        return st

    yield make
    for st in running:
        st.stop()
