"""Every typed method of Gripper and AsyncGripper against the real virtual gripper over TCP, UDP and
a pty, on the real clock with fast motion (5000 mm/s², 400 mm/s)."""

from __future__ import annotations

import pytest

from pywsg import AsyncGripper, Gripper
from pywsg.errors import CommandUnknownError, FastStopError, NotAvailableError
from pywsg.protocol import DeviceType, FingerFlag, FingerType, GripperState, Status, SystemFlag

from .conftest import FAST, SimThread

TRANSPORTS = ["tcp", "udp", "serial"]


def near(a: float, b: float, tol: float = 0.15) -> bool:
    return abs(a - b) <= tol


@pytest.mark.realtime
@pytest.mark.parametrize("kind", TRANSPORTS)
def test_every_method_sync(sim: SimThread, kind: str) -> None:
    dev = sim.device
    with Gripper(sim.url(kind), timeout=2) as g:
        assert g.loop(b"\x00abc\xff") == b"\x00abc\xff"
        info = g.info()
        assert info.type == DeviceType.WSG50 and info.serial_number == 10001
        assert info.firmware_version.count(".") == 2
        lim = g.limits()
        assert lim.stroke == 110.0 and lim.max_speed == 420.0 and lim.nominal_force == 80.0
        assert SystemFlag.SF_REFERENCED not in g.system_state()
        g.home()
        assert SystemFlag.SF_REFERENCED in g.system_state()
        assert near(g.width(), 110.0)
        g.set_acceleration(4000)
        assert g.acceleration() == 4000.0
        g.set_force_limit(40)
        assert g.force_limit() == 40.0
        g.move(60, FAST)
        assert near(g.width(), 60.0)
        g.move(-10, FAST, relative=True)
        assert near(g.width(), 50.0)
        assert g.speed() == 0.0
        sim.call(lambda: dev.faults.place_part(30))
        g.grip(30, FAST, force=20)
        assert g.gripper_state() == GripperState.HOLDING
        assert near(g.force(), 20.0, 0.5)
        st = g.state()
        assert st.gripper_state == GripperState.HOLDING and near(st.width, 30.0, 0.5)
        assert SystemFlag.SF_REFERENCED in st.flags and 10 < st.temperature < 80
        g.release(60, FAST)
        assert near(g.width(), 60.0)
        sim.call(dev.faults.remove_part)
        assert g.statistics().total == 1
        assert g.statistics(reset=True).total == 1
        assert g.statistics().total == 0
        assert g.soft_limits() is None
        g.set_soft_limits(5, 105)
        limits = g.soft_limits()
        assert limits is not None and (limits.minus, limits.plus) == (5.0, 105.0)
        g.clear_soft_limits()
        assert g.soft_limits() is None
        g.overdrive(True)
        assert SystemFlag.SF_OVERDRIVE_MODE in g.system_state()
        g.overdrive(False)
        assert SystemFlag.SF_OVERDRIVE_MODE not in g.system_state()
        g.tare()
        assert 10 < g.temperature() < 80
        assert g.tag() is None
        g.set_tag("station 3")
        assert g.tag() == "station 3"
        f1 = g.finger(1).info()
        assert f1.type == FingerType.WSG_FMF
        assert isinstance(g.finger(1).flags(), FingerFlag)
        assert isinstance(g.finger(1).data(), bytes)
        assert g.finger(2).info().type == FingerType.GENERIC
        g.finger(2).power(True)
        assert FingerFlag.POWER_ON in g.finger(2).flags()
        g.finger(2).power(False)
        with pytest.raises(NotAvailableError):
            g.finger(2).data()
        g.stop()
        assert SystemFlag.SF_AXIS_STOPPED in g.system_state()
        g.fast_stop()
        with pytest.raises(FastStopError) as ei:
            g.move(40, FAST)
        assert ei.value.flags is not None and SystemFlag.SF_FAST_STOP in ei.value.flags
        g.acknowledge()
        g.move(40, FAST)
        assert g.request(0x06, b"xy").params == b"xy"
        with pytest.raises(CommandUnknownError):
            g.request(0xB0)
        r = g.request(0xB0, check=False)
        assert r.status == Status.E_CMD_UNKNOWN


@pytest.mark.realtime
@pytest.mark.parametrize("kind", TRANSPORTS)
async def test_every_method_async(sim: SimThread, kind: str) -> None:
    dev = sim.device
    async with AsyncGripper(sim.url(kind), timeout=2) as g:
        assert await g.loop(b"ping") == b"ping"
        assert (await g.info()).type == DeviceType.WSG50
        assert (await g.limits()).stroke == 110.0
        await g.home()
        assert near(await g.width(), 110.0)
        await g.set_acceleration(4500)
        assert await g.acceleration() == 4500.0
        await g.set_force_limit(30)
        assert await g.force_limit() == 30.0
        await g.move(70, FAST)
        await g.move(-20, FAST, relative=True)
        assert near(await g.width(), 50.0)
        assert await g.speed() == 0.0
        sim.call(lambda: dev.faults.place_part(25))
        await g.grip(25, FAST, force=25)
        assert await g.gripper_state() == GripperState.HOLDING
        assert near(await g.force(), 25.0, 0.5)
        st = await g.state()
        assert st.gripper_state == GripperState.HOLDING
        await g.release(60, FAST)
        sim.call(dev.faults.remove_part)
        assert (await g.statistics()).total == 1
        await g.set_soft_limits(2, 108)
        assert (await g.soft_limits()) is not None
        await g.clear_soft_limits()
        assert await g.soft_limits() is None
        await g.overdrive(True)
        assert SystemFlag.SF_OVERDRIVE_MODE in await g.system_state()
        await g.overdrive(False)
        await g.tare()
        assert 10 < await g.temperature() < 80
        await g.set_tag("cell-7")
        assert await g.tag() == "cell-7"
        assert (await g.finger(1).info()).type == FingerType.WSG_FMF
        assert isinstance(await g.finger(1).flags(), FingerFlag)
        assert isinstance(await g.finger(1).data(), bytes)
        await g.finger(2).power(True)
        await g.finger(2).power(False)
        await g.stop()
        await g.fast_stop()
        with pytest.raises(FastStopError):
            await g.grip(10, FAST)
        await g.acknowledge()
        await g.move(45, FAST)
        assert near(await g.width(), 45.0)
        assert (await g.request(0x06, b"raw")).params == b"raw"
        with pytest.raises(CommandUnknownError):
            await g.request(0xB1)
