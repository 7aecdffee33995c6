"""Fixtures: the real virtual gripper served by ``SimServer`` (TCP, UDP, pty) on its own event loop
in a background thread, so both the blocking and the asyncio driver can talk to it. Motion is fast:
acceleration 5000 mm/s² (the WSG 50's maximum) and speeds up to 420 mm/s, on the real clock."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from typing import Any

import pytest

from pywsg.device import Settings, VirtualGripper

from ..simthread import SimThread as BaseSimThread
from ..simthread import started

FAST = 400.0  # mm/s


def fast_factory(model: str, settings: Any, clock: Any) -> VirtualGripper:
    s = (settings or Settings()).updated(default_acceleration=5000.0, finger1="fmf")
    return VirtualGripper(model, settings=s, **({"clock": clock} if clock is not None else {}))


class SimThread(BaseSimThread):
    """The sim with fast motion and every interface on (TCP, UDP, pty); settings are not saved."""

    save_on_stop = False

    def __init__(self, **options: Any) -> None:
        super().__init__(**{"factory": fast_factory, "tcp_port": 0, "udp_port": 0, "serial": "pty", **options})

    @property
    def device(self) -> VirtualGripper:
        g: VirtualGripper = self.sim.grippers[0].gripper
        return g

    def url(self, kind: str) -> str:
        sg = self.sim.grippers[0]
        if kind == "tcp":
            return str(sg.tcp_url)
        if kind == "udp":  # the sim replies to the sender's port: bind any free reply port
            return f"udp://127.0.0.1:{self.sim.udp_port}?reply_port=0"
        return f"serial://{self.sim.serial_path}?baudrate=115200"


@pytest.fixture
def sim_factory() -> Iterator[Callable[..., SimThread]]:
    yield from started(SimThread)


@pytest.fixture
def sim(sim_factory: Callable[..., SimThread]) -> SimThread:
    return sim_factory()
