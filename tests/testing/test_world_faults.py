"""The faults WSG users ask for (issue 27 item 2), each checked against what the manuals say a real WSG
reports, through pywsg's own driver on a manual clock (docs/testing.md, "World faults")."""

from __future__ import annotations

import time

import pytest

from pywsg.client import Gripper
from pywsg.errors import AccessDeniedError, ConnectionLostError, WsgError
from pywsg.protocol import FingerFlag, GripperState, SystemFlag
from pywsg.testing import SimThread, WorldError

pytestmark = pytest.mark.wsg_sim(clock="manual")


def _home(sim: SimThread, g: Gripper) -> None:
    m = g.home(wait=False)
    sim.world.advance(5.0)
    m.wait(5)


def test_acknowledge_refused_keeps_the_fast_stop(wsg_sim: SimThread) -> None:
    """000 §3.2.5: a FAST STOP is acknowledged "after fixing the corresponding error cause"."""
    with Gripper(wsg_sim.url, timeout=2) as g:
        g.fast_stop()
        assert wsg_sim.world.fault("ack") == "acknowledge refused on"
        with pytest.raises(AccessDeniedError, match="acknowledge refused"):
            g.acknowledge()
        assert g.system_state() & SystemFlag.SF_FAST_STOP  # Appendix B D12 stays
        assert "acknowledge refused" in wsg_sim.world.state()["faults"]
        wsg_sim.world.fault("ack", on=False)
        g.acknowledge()
        assert not g.system_state() & SystemFlag.SF_FAST_STOP


def test_connection_interrupted_by_the_gripper_leaves_a_fast_stop(wsg_sim: SimThread) -> None:
    """000 §1.4.2: a TCP session that ends without 07h raises FAST STOP; reconnecting finds it."""
    seen: list[SystemFlag] = []
    with Gripper(wsg_sim.url, timeout=2, reconnect=True) as g:
        g.on_reconnect = seen.append
        _home(wsg_sim, g)
        assert wsg_sim.world.disconnect() == "connections interrupted by the gripper"
        try:
            g.width()  # the call that meets the closed connection fails, unless the driver reconnected first
        except ConnectionLostError:
            pass
        flags = g.system_state()  # reconnected by the driver
        assert flags & SystemFlag.SF_FAST_STOP
        deadline = time.monotonic() + 10  # on_reconnect runs on the driver's reconnecting thread
        while not seen and time.monotonic() < deadline:
            time.sleep(0.01)
        assert seen and seen[0] & SystemFlag.SF_FAST_STOP  # on_reconnect: reported, not acknowledged
        assert g.gripper_state() == GripperState.ERROR  # 001 §3.4.2: FAST STOP -> ERROR
        with pytest.raises(AccessDeniedError):  # 000 §3.2.4: motion refused until 24h
            g.move(50.0, 100.0, wait=False)
        g.acknowledge()


def test_watchdog_fast_stops_a_client_that_stays_silent(wsg_sim: SimThread) -> None:
    with Gripper(wsg_sim.url, timeout=2) as g:
        wsg_sim.world.fault("watchdog", timeout=5.0)
        wsg_sim.world.advance(4.0)
        g.loop(b"alive")  # a request restarts the count
        wsg_sim.world.advance(4.0)
        assert not wsg_sim.world.state()["fast_stop"]
        wsg_sim.world.advance(1.5)  # 5.5 s since the last request
        assert wsg_sim.world.state()["fast_stop"]
        assert g.system_state() & SystemFlag.SF_FAST_STOP
        wsg_sim.world.fault("watchdog", on=False)
        g.acknowledge()
        wsg_sim.world.advance(60.0)
        assert not wsg_sim.world.state()["fast_stop"]  # off: no more FAST STOPs


def test_slipping_part_is_lost_on_time(wsg_sim: SimThread) -> None:
    """000 §3.4.2 state 3 PART LOST; §3.4.3 LOST_PART counts it."""
    with Gripper(wsg_sim.url, timeout=2) as g:
        _home(wsg_sim, g)
        wsg_sim.world.place_part(22.0)
        m = g.grip(22.0, speed=100, wait=False)
        wsg_sim.world.advance(3.0)
        m.wait(5)
        assert g.gripper_state() == GripperState.HOLDING
        lost_before = g.statistics().lost_part
        assert wsg_sim.world.slip(duration=2.0) == "part slipping out, gone in 2 s"
        wsg_sim.world.advance(1.9)
        assert g.gripper_state() == GripperState.HOLDING
        assert "part slipping" in wsg_sim.world.state()["faults"]
        wsg_sim.world.advance(0.2)
        assert g.gripper_state() == GripperState.PART_LOST
        assert g.statistics().lost_part == lost_before + 1
        assert wsg_sim.world.state()["part"] is None


def test_slip_without_a_part_is_refused(wsg_sim: SimThread) -> None:
    with pytest.raises(WorldError, match="part: no part between the fingers"):
        wsg_sim.world.slip()


@pytest.mark.wsg_sim(clock="manual", settings={"finger1": "fmf"})
def test_unplugged_sensor_finger_reports_a_communication_fault(wsg_sim: SimThread) -> None:
    """000 §3.6.2 COMM_FAULT "during runtime", Appendix B D17 SF_FINGER_FAULT, 63h E_IO_ERROR."""
    with Gripper(wsg_sim.url, timeout=2) as g:
        f1 = g.finger(1)
        assert f1.flags() & FingerFlag.COMM_OPEN
        f1.data()
        wsg_sim.world.fault("unplugged", finger=1)
        flags = f1.flags()
        assert flags & FingerFlag.COMM_FAULT
        assert not flags & (FingerFlag.COMM_OPEN | FingerFlag.CONFIG_AVAIL)
        assert g.system_state() & SystemFlag.SF_FINGER_FAULT
        with pytest.raises(WsgError, match="E_IO_ERROR"):
            f1.data()
        wsg_sim.world.fault("unplugged", finger=1, on=False)
        assert f1.data()
        assert not g.system_state() & SystemFlag.SF_FINGER_FAULT


def test_unplugged_generic_finger_changes_nothing_the_protocol_shows(wsg_sim: SimThread) -> None:
    """000 §3.6.1: type 0 means "generic or no finger installed": a real WSG cannot tell."""
    with Gripper(wsg_sim.url, timeout=2) as g:
        before = (g.finger(2).flags(), g.system_state())
        wsg_sim.world.fault("unplugged", finger=2)
        assert (g.finger(2).flags(), g.system_state()) == before
        assert "finger 2 unplugged" in wsg_sim.world.state()["faults"]
