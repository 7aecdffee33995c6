"""The pytest plugin (entry point ``pytest11: pywsg``): a fresh virtual gripper per test.

::

    def test_pick(wsg_sim):                    # blocking test
        wsg_sim.world.place_part(22.0)
        with Gripper(wsg_sim.url) as g:
            g.home(); assert g.grip(22.0, speed=100).state == "HOLDING"

    @pytest.mark.wsg_sim(model="wsg32", clock="manual")
    async def test_async(wsg_sim): ...         # async tests too (the server has its own thread)

    @pytest.mark.parametrize("wsg_sim", [{"model": "wsg25"}, {"model": "wsg70"}], indirect=True)
    def test_each_model(wsg_sim): ...

    @pytest.mark.wsg_cell(count=2, clock="manual")
    def test_station(wsg_cell):                # a cell: several grippers, each with its own world
        left, right = wsg_cell
        left.world.place_part(22.0)
        with Gripper(left.url) as a, Gripper(right.url) as b: ...

Options (marker keywords or the parameter dict) are those of :class:`~pywsg.testing.SimThread`:
``model``, ``clock="manual"``, ``time_scale``, ``count``, ``scenario``, ``settings``, ports,
``udp_reply_port``, ``limits``.
All grippers of a test session share one server thread, so a fresh gripper costs only its sockets.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import pytest

from .host import LoopThread, SimThread

_LOOP: LoopThread | None = None


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line(
        "markers",
        "wsg_sim(**options): options for the wsg_sim fixture (model, clock='manual', scenario, settings, ...)",
    )
    config.addinivalue_line(
        "markers", "wsg_cell(count=2, **options): options for the wsg_cell fixture (a cell of grippers)",
    )


def pytest_unconfigure(config: pytest.Config) -> None:
    global _LOOP
    if _LOOP is not None:
        _LOOP.close()
        _LOOP = None


def _shared_loop() -> LoopThread:
    global _LOOP
    if _LOOP is None or _LOOP.loop.is_closed():
        _LOOP = LoopThread("pywsg-wsg_sim")
    return _LOOP


def _options(request: pytest.FixtureRequest, name: str, base: dict[str, Any]) -> dict[str, Any]:
    options = dict(base)
    for mark in reversed(list(request.node.iter_markers(name))):  # closest marker wins
        options.update(mark.kwargs)
    param = getattr(request, "param", None)
    if param is not None:
        if not isinstance(param, dict):
            raise TypeError(f"{name} parameter: a dict of SimThread options, e.g. {{'model': 'wsg32'}}")
        options.update(param)
    return options


@pytest.fixture
def wsg_sim(request: pytest.FixtureRequest) -> Iterator[SimThread]:
    """A fresh virtual WSG for this test: ``.url``, ``.udp_url``, ``.serial_url``, ``.modbus_port``,
    ``.world`` (parts, obstacles, faults, heat, network faults, ``advance(dt)`` on a manual clock),
    ``.assert_replays(recording)``."""
    yield from _serve(_options(request, "wsg_sim", {}))


@pytest.fixture
def wsg_cell(request: pytest.FixtureRequest) -> Iterator[SimThread]:
    """A cell of fresh virtual WSGs (``count``, default 2): ``wsg_cell[i].url``, ``wsg_cell[i].world``;
    iterate it (``left, right = wsg_cell``). On a manual clock they share the time:
    ``wsg_cell[0].world.advance(dt)`` moves every gripper on."""
    yield from _serve(_options(request, "wsg_cell", {"count": 2}))


def _serve(options: dict[str, Any]) -> Iterator[SimThread]:
    sim = SimThread(loop=_shared_loop(), **options)
    sim.save_on_stop = False  # a test must not write a settings file it was only given to read
    sim.start()
    try:
        yield sim
    finally:
        sim.stop()
