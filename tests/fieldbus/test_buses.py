"""One controller, many buses (device side) and one gripper over any image exchange (PLC side).

The fail-safe decision (a bus master lost → FAST STOP, outputs to zero) is docs/fidelity.md
"Fieldbus master lost", from 000 §1.4.2 (lost connections are severe errors: FAST STOP) and the
fieldbus manuals' FAST STOP and STOP/ACK rules (002 §4.5, §4.6 / 003 §5.5, §5.6).
"""

from __future__ import annotations

import asyncio
import importlib
from collections.abc import AsyncIterator
from typing import Any

import httpx
import pytest
from click.testing import CliRunner

from pywsg.cli.plc import plc_demo
from pywsg.fieldbus import exchange as exchange_mod
from pywsg.fieldbus.bus import BusAdapter
from pywsg.fieldbus.exchange import FieldbusConnectionError, ImageExchange, open_exchange
from pywsg.fieldbus.image import CmdFlag, OutputImage
from pywsg.fieldbus.modbus.exchange import ModbusExchange
from pywsg.fieldbus.plc import AsyncFieldbusGripper, FieldbusGripper
from pywsg.protocol import GripperState, Status, SystemFlag
from pywsg.server import SimServer
from pywsg.web.fieldbus_view import fieldbus_view

from .test_controller import Rig

C = CmdFlag
SF = SystemFlag
GS = GripperState


class RowsBus:
    """A bus adapter that only reports rows: what a PROFINET or PROFIBUS adapter gives the monitor."""

    name = "PROFIBUS DP"

    def __init__(self) -> None:
        self.closed = False

    def bus_state(self) -> dict[str, str]:
        return {"Station Address": "7", "Bitrate": "1.5 Mbit/s", "Interface state": "Data exchange"}

    async def close(self) -> None:
        self.closed = True


def test_attach_and_detach_buses() -> None:
    r = Rig()
    bus = RowsBus()
    assert isinstance(bus, BusAdapter)
    assert r.ctl.buses == ()
    r.ctl.attach_bus(bus)
    r.ctl.attach_bus(bus)          # attaching twice lists it once
    assert r.ctl.buses == (bus,)
    r.ctl.detach_bus(bus)
    r.ctl.detach_bus(bus)          # detaching an unknown bus is no error
    assert r.ctl.buses == ()


def test_fail_safe_during_a_move_fast_stops_and_drops_the_outputs() -> None:
    """A master lost mid-MOVE: FAST STOP (000 §1.4.2), STATUS E_CMD_ABORTED, outputs all zero,
    IF flags cleared; GSTATE IDLE as after any FAST STOP (002 §4.6)."""
    r = Rig()
    r.home()
    r.write(C.MOVE, width=10, speed=50, if_flags=0x05)
    r.run(0.05)
    assert r.ctl.input_image().sysstate & SF.SF_MOVING
    assert r.g.script_if == 0x05
    r.ctl.fail_safe("PROFINET IO", "AR watchdog expired")
    img = r.ctl.input_image()
    assert img.sysstate & SF.SF_FAST_STOP and not img.sysstate & SF.SF_MOVING
    assert img.status == Status.E_CMD_ABORTED and img.state == GS.IDLE
    assert r.ctl.output_image == OutputImage() and r.g.script_if == 0
    assert any("PROFINET IO master lost (AR watchdog expired)" in e.text for e in r.ctl.events)
    width = img.width
    r.run(1.0)
    assert r.ctl.input_image().width == width      # the fingers stay where they stopped


def test_fail_safe_stops_a_jog_and_the_returning_master_acknowledges() -> None:
    """After the loss, the master's first image is read against zeros: a held MOVE bit is a new edge,
    refused under FAST STOP (E_ACCESS_DENIED); STOP/ACK acknowledges as usual (002 §4.5)."""
    r = Rig()
    r.home()
    r.write(C.JOG_MINUS, speed=20, force=0)    # homing ends open: jog closing
    r.run(0.05)
    assert r.ctl.input_image().sysstate & SF.SF_MOVING
    r.ctl.fail_safe("PROFIBUS DP", "Global_Control Clear")
    r.run(0.5)
    img = r.ctl.input_image()
    assert img.sysstate & SF.SF_FAST_STOP and not img.sysstate & SF.SF_MOVING
    img = r.write(C.MOVE, width=50, speed=50)           # the master comes back with MOVE still raised
    assert img.status == Status.E_ACCESS_DENIED and img.sysstate & SF.SF_FAST_STOP
    r.write(C.NONE)
    img = r.pulse(C.STOP_ACK)
    r.run(0.05)
    img = r.ctl.input_image()
    assert not img.sysstate & SF.SF_FAST_STOP and img.state == GS.IDLE
    r.pulse(C.MOVE, width=50, speed=50)
    img = r.settle()
    assert img.status == Status.E_SUCCESS and abs(img.width - 5000) <= 1


def test_fail_safe_at_rest_also_fast_stops() -> None:
    """As the unannounced TCP close (000 §1.4.2): the FAST STOP does not wait for a motion."""
    r = Rig()
    r.home()
    r.ctl.fail_safe("PROFINET IO", "AR aborted")
    img = r.ctl.input_image()
    assert img.sysstate & SF.SF_FAST_STOP and img.status == Status.E_CMD_ABORTED


@pytest.fixture
async def sim() -> AsyncIterator[SimServer]:
    async with SimServer(tcp_port=None, udp_port=None, modbus_port=0, web_port=0) as s:
        yield s


@pytest.mark.realtime
async def test_the_sim_makes_one_controller_that_the_modbus_server_and_web_share(sim: SimServer) -> None:
    sg = sim.grippers[0]
    ctl = sg.controller
    assert ctl is not None and sg.fieldbus_controller() is ctl    # one per gripper, made once
    assert sg.modbus.controller is ctl and ctl.buses == (sg.modbus,)
    assert sg.web.app.state.ctx.fieldbus is ctl
    # a second bus on the same controller shows in the Fieldbus Monitor with its own rows
    bus = RowsBus()
    ctl.attach_bus(bus)
    async with httpx.AsyncClient(base_url=f"http://127.0.0.1:{sg.web_port}") as web:
        buses = (await web.get("/api/fieldbus")).json()["buses"]
    assert [b["name"] for b in buses] == ["Modbus/TCP", "PROFIBUS DP"]
    assert buses[0]["rows"][0] == {"label": "Interface", "text": f"Modbus/TCP (port {sg.modbus_port})"}
    assert buses[0]["rows"][-1]["text"].startswith("Waiting: no Modbus master connected")
    assert buses[1]["rows"] == [{"label": "Station Address", "text": "7"},
                                {"label": "Bitrate", "text": "1.5 Mbit/s"},
                                {"label": "Interface state", "text": "Data exchange"}]
    ctl.detach_bus(bus)


def test_a_failing_bus_state_does_not_take_the_monitor_down() -> None:
    r = Rig()

    class Broken(RowsBus):
        name = "PROFINET IO"

        def bus_state(self) -> dict[str, str]:
            raise RuntimeError("boom")

    r.ctl.attach_bus(Broken())
    view = fieldbus_view(r.ctl)
    assert view["buses"] == [{"name": "PROFINET IO", "rows": [{"label": "Interface state",
                                                               "text": "unknown (RuntimeError)"}]}]


@pytest.mark.realtime
async def test_the_plc_side_runs_over_an_exchange_opened_by_url(sim: SimServer) -> None:
    url = f"modbus-tcp://127.0.0.1:{sim.modbus_port}"
    ex = await open_exchange(url, timeout=5)
    assert isinstance(ex, ModbusExchange) and isinstance(ex, ImageExchange)
    plc = await AsyncFieldbusGripper.start(ex)
    try:
        img = await plc.homing()
        assert img.status == Status.E_SUCCESS and img.sysstate & SF.SF_REFERENCED
        img = await plc.move(40.0, 100.0)
        assert abs(img.width_mm - 40.0) < 0.05
        assert sim.grippers[0].controller.output_image.width == 4000   # the bytes arrived in image order
    finally:
        await plc.close()


@pytest.mark.realtime
async def test_the_blocking_gripper_takes_a_url(sim: SimServer) -> None:
    def run() -> float:
        with FieldbusGripper(f"modbus-tcp://127.0.0.1:{sim.modbus_port}") as plc:
            plc.homing()
            return plc.move(20.0, 100.0).width_mm

    assert abs(await asyncio.to_thread(run) - 20.0) < 0.05


async def test_open_exchange_names_what_is_wrong(monkeypatch: pytest.MonkeyPatch) -> None:
    with pytest.raises(ValueError, match="unknown fieldbus URL scheme 'can'"):
        await open_exchange("can://can0")
    with pytest.raises(ValueError, match="bad port"):
        await open_exchange("modbus-tcp://127.0.0.1:99999")
    # a bus this installation does not have
    monkeypatch.setitem(exchange_mod.SCHEMES, "ethercat", "ethercat")
    with pytest.raises(FieldbusConnectionError, match=r"has no ethercat master \(pywsg.fieldbus.ethercat"):
        await open_exchange("ethercat://eth0")
    # a bus whose optional extra is missing: the import error names the module and the extra
    real = importlib.import_module

    def without_pnio(name: str, package: str | None = None) -> Any:
        if name == "pywsg.fieldbus.profinet.exchange":
            raise ModuleNotFoundError("No module named 'pnio_dcp'", name="pnio_dcp")
        return real(name, package)

    monkeypatch.setattr(exchange_mod.importlib, "import_module", without_pnio)
    with pytest.raises(FieldbusConnectionError, match=r"needs 'pnio_dcp': pip install 'pywsg\[profinet\]'"):
        await open_exchange("profinet://eth0/wsg50")


def test_plc_demo_refuses_an_unknown_url_scheme() -> None:
    res = CliRunner().invoke(plc_demo, ["--url", "can://can0"])
    assert res.exit_code == 2 and "unknown fieldbus URL scheme" in res.output
