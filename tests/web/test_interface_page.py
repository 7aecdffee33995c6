"""Settings → Command Interface (issue 15 item 9) and the Fieldbus Monitor's Bus State.

The stored values: active interface, PROFIBUS station address (predefined 7, 002 §2.1.2 / 003
§2.2), PROFINET device name (003 §3.2), IP settings (delivery state 192.168.1.20, 000 §1.1).
The Bus State (003 §6): Station Address, Bitrate, Interface state from a real Modbus/TCP master.
"""

from __future__ import annotations

import dataclasses
import json
import time
from collections.abc import Iterator
from typing import Any

import httpx
import pytest
from fastapi.testclient import TestClient
from pymodbus.client import ModbusTcpClient

from pywsg.device import Settings, VirtualGripper
from pywsg.fieldbus.controller import FieldbusController
from pywsg.web.app import create_app
from pywsg.web.interface_page import InterfaceConfig, store_path

from .conftest import ARTIFACTS, LiveSim, wait_for

DEFAULTS = dataclasses.asdict(InterfaceConfig())


@pytest.fixture(autouse=True)
def defaults(api: httpx.Client) -> Iterator[None]:
    assert api.post("/api/interface", json=DEFAULTS).status_code == 200
    yield


def test_defaults_are_the_delivery_state(api: httpx.Client) -> None:
    body = api.get("/api/interface").json()
    assert body["values"]["profibus_address"] == 7  # 002 §2.1.2 "predefined to 7"
    assert body["values"]["ip_address"] == "192.168.1.20"  # 000 §1.1 default address
    assert body["values"]["interface"] == "tcp"
    # every field carries its "stored, not applied" note
    assert set(body["notes"]) == set(DEFAULTS) and all("not applied" in n for n in body["notes"].values())


def test_values_are_stored_beside_the_settings_file_and_survive_a_restart(sim: LiveSim, api: httpx.Client) -> None:
    change = {"interface": "profibus", "profibus_address": 12, "profinet_name": "wsg50-cell1.line-2",
              "ip_address": "10.0.0.5", "netmask": "255.255.0.0", "gateway": "10.0.0.1", "dhcp": True}
    r = api.post("/api/interface", json=change)
    assert r.status_code == 200, r.text
    assert r.json()["changed"] == sorted(change)
    path = store_path(sim.settings_path)
    assert path is not None and json.loads(path.read_text()) == {**DEFAULTS, **change}
    # the device's own settings file stays loadable (its Settings refuse unknown keys)
    sim.call(lambda: sim.gripper.settings.save(sim.settings_path))
    Settings.load(sim.settings_path)
    # a new web interface on the same settings file shows the stored values
    fresh = TestClient(create_app(VirtualGripper("wsg50", settings=Settings()), settings_path=sim.settings_path),
                       base_url="http://127.0.0.1")
    assert fresh.get("/api/interface").json()["values"] == {**DEFAULTS, **change}


@pytest.mark.parametrize(("field", "value"), [
    ("profibus_address", 126), ("profibus_address", -1), ("profibus_address", True), ("profibus_address", "7"),
    ("profinet_name", "WSG_50"), ("profinet_name", "port-001"), ("profinet_name", "-wsg"),
    ("profinet_name", "a" * 64), ("profinet_name", "1.2.3.4"),
    ("interface", "ethercat"), ("dhcp", "yes"),
    ("ip_address", "300.1.1.1"), ("ip_address", "127.0.0.1"), ("ip_address", "192.168.1.255"),
    ("netmask", "255.0.255.0"), ("gateway", "10.9.9.9"), ("nonsense", 1),
])
def test_invalid_values_are_refused_per_field_and_store_nothing(sim: LiveSim, api: httpx.Client, field: str,
                                                                value: Any) -> None:
    before = api.get("/api/interface").json()["values"]
    r = api.post("/api/interface", json={field: value})
    assert r.status_code == 422
    assert field in r.json()["errors"], r.json()
    assert api.get("/api/interface").json()["values"] == before


def test_malformed_bodies_and_missing_csrf_are_refused(sim: LiveSim, api: httpx.Client) -> None:
    assert api.post("/api/interface", content=b"{").status_code == 422
    assert api.post("/api/interface", json=[1]).status_code == 422
    assert api.post("/api/interface", json={}).status_code == 422
    assert httpx.post(sim.url + "/api/interface", json={"profibus_address": 9}).status_code == 403
    assert api.get("/api/interface").json()["values"]["profibus_address"] == 7


def _bus(api: httpx.Client) -> dict[str, Any]:
    return dict(api.get("/api/fieldbus").json()["bus"])


def test_bus_state_follows_a_real_modbus_master(sim: LiveSim, api: httpx.Client) -> None:
    """003 §6 Interface state: online while a master is connected; the time of its last write."""
    wait_for(lambda: _bus(api)["masters"] == 0)
    assert _bus(api)["state"] == "waiting" and _bus(api)["port"] == sim.modbus.port
    with ModbusTcpClient("127.0.0.1", port=sim.modbus.port) as mb:
        assert mb.connect()
        wait_for(lambda: _bus(api)["state"] == "online")
        assert _bus(api)["masters"] == 1
        before = _bus(api)["last_write"]
        t0 = time.time()
        assert not mb.write_register(1, 0).isError()  # WIDTH: no command edge
        bus = _bus(api)
        assert bus["last_write"] is not None and bus["last_write"] != before and t0 - 0.01 <= bus["last_write"]
        assert bus["last_write"] <= bus["now"]
        assert not mb.read_input_registers(0, count=6).isError()  # a read is not a write
        assert _bus(api)["last_write"] == bus["last_write"]
    wait_for(lambda: _bus(api)["state"] == "waiting")


def test_bus_state_without_a_modbus_server_is_offline() -> None:
    g = VirtualGripper("wsg50", settings=Settings())
    c = TestClient(create_app(g, fieldbus=FieldbusController(g)), base_url="http://127.0.0.1")
    bus = c.get("/api/fieldbus").json()["bus"]
    assert bus["state"] == "offline" and bus["masters"] == 0


@pytest.mark.browser
def test_command_interface_page_stores_values_with_notes(sim: LiveSim, page: Any) -> None:
    page.goto(sim.url + "/settings/interface")
    assert page.inner_text("main h1") == "Command Interface"
    page.wait_for_selector("#iface-form[data-loaded='1']")
    page.wait_for_selector("#settings-form[data-loaded='1']")
    assert page.locator("#set-crc_check").count() == 1  # the real protocol options stay on the page
    notes = page.locator("#iface-form .not-applied")
    assert notes.count() == 7
    for i in range(7):
        assert notes.nth(i).is_visible() and "not applied" in notes.nth(i).inner_text()
    assert page.input_value("#if-profibus_address") == "7"
    # out of range: the browser refuses to submit (the range is on the input); a bad name: the server says why
    page.fill("#if-profibus_address", "200")
    assert page.eval_on_selector("#if-profibus_address", "e => e.validity.rangeOverflow")
    page.fill("#if-profibus_address", "12")
    page.fill("#if-profinet_name", "WSG_50")
    page.click("#iface-save")
    page.wait_for_selector(".field-error[data-for='profinet_name']:not(:empty)")
    assert "a-z" in page.inner_text(".field-error[data-for='profinet_name']")
    assert page.inner_text("#iface-result").startswith("Not stored")
    page.select_option("#if-interface", "profinet")
    page.fill("#if-profibus_address", "12")
    page.fill("#if-profinet_name", "wsg50-cell1")
    page.fill("#if-ip_address", "192.168.1.30")
    page.click("#iface-save")
    page.wait_for_function("document.getElementById('iface-result').textContent.startsWith('Stored')")
    page.reload()
    page.wait_for_selector("#iface-form[data-loaded='1']")
    assert page.input_value("#if-interface") == "profinet"
    assert page.input_value("#if-profinet_name") == "wsg50-cell1"
    assert page.input_value("#if-ip_address") == "192.168.1.30"
    page.screenshot(path=str(ARTIFACTS / "command-interface.png"), full_page=True)
    # the Fieldbus Monitor shows the bus state: the rows the Modbus/TCP server gives (003 §6)
    page.goto(sim.url + "/diagnosis/fieldbus")
    state = "document.querySelector(\"#fb-bus td[data-row='Interface state']\")"
    page.wait_for_function(f"{state} && {state}.textContent.startsWith('Waiting')")
    assert page.inner_text("#fb-bus td[data-row='Interface']") == f"Modbus/TCP (port {sim.modbus.port})"
    with ModbusTcpClient("127.0.0.1", port=sim.modbus.port) as mb:
        assert not mb.write_register(1, 0).isError()
        page.wait_for_function(f"{state}.textContent.startsWith('Online: 1 master connected, last write')")
    page.wait_for_function(f"{state}.textContent.startsWith('Waiting')")
