"""Scripting page (issue 15 item 8): the running firmware plugin, start/stop, SF_SCRIPT_RUNNING/FAILURE.

The flags are 000 Appendix B D19 SF_SCRIPT_RUNNING and D20 SF_SCRIPT_FAILURE; a started plugin's
command IDs answer over a real TCP connection, a stopped one's are E_CMD_UNKNOWN.
"""

from __future__ import annotations

import socket
from collections.abc import Iterator
from typing import Any

import httpx
import pytest

from pywsg.device.plugins import PLUGINS, FirmwarePlugin, ScriptHost
from pywsg.protocol import Frame, SystemFlag

from .conftest import LiveSim, read_status, wait_for


@pytest.fixture(autouse=True)
def no_script(sim: LiveSim, api: httpx.Client) -> Iterator[None]:
    api.post("/api/scripting/stop")
    yield
    api.post("/api/scripting/stop")


def b0h_status(sim: LiveSim) -> str:
    """Send B0h (ros_measure's / umi_measure's measure command) over TCP; the reply's status name."""
    with socket.create_connection(("127.0.0.1", sim.tcp.port), timeout=3) as s:
        s.sendall(Frame(0xB0, b"").encode())
        return read_status(s)


def flags(sim: LiveSim) -> SystemFlag:
    return SystemFlag(sim.snapshot().flags)


def test_start_and_stop_a_script_sets_sf_script_running(sim: LiveSim, api: httpx.Client) -> None:
    """000 Appendix B D19: SF_SCRIPT_RUNNING while a script runs; its commands answer only then."""
    view = api.get("/api/scripting").json()
    assert view["running"] == [] and not view["script_running"]
    assert {p["name"] for p in view["available"]} == set(PLUGINS)
    assert b0h_status(sim) == "E_CMD_UNKNOWN"

    r = api.post("/api/scripting/start", json={"plugin": "ros_measure"})
    assert r.status_code == 200, r.text
    assert r.json()["running"] == ["ros_measure"] and r.json()["script_running"]
    assert SystemFlag.SF_SCRIPT_RUNNING in flags(sim)
    assert b0h_status(sim) == "E_SUCCESS"

    r = api.post("/api/scripting/stop")
    assert r.status_code == 200 and r.json()["running"] == [] and not r.json()["script_running"]
    assert SystemFlag.SF_SCRIPT_RUNNING not in flags(sim)
    assert b0h_status(sim) == "E_CMD_UNKNOWN"


def test_starting_another_script_stops_the_first(sim: LiveSim, api: httpx.Client) -> None:
    api.post("/api/scripting/start", json={"plugin": "ros_measure"})
    r = api.post("/api/scripting/start", json={"plugin": "umi_measure"})
    assert r.status_code == 200 and r.json()["running"] == ["umi_measure"]
    assert sim.snapshot().plugins == ("umi_measure",)


def test_bad_requests_are_refused_and_change_nothing(sim: LiveSim, api: httpx.Client) -> None:
    api.post("/api/scripting/start", json={"plugin": "ros_measure"})
    r = api.post("/api/scripting/start", json={"plugin": "../etc"})
    assert r.status_code == 422 and "plugin" in r.json()["errors"]
    r = api.post("/api/scripting/start", json={"plugin": 3})
    assert r.status_code == 422
    no_csrf = httpx.post(sim.url + "/api/scripting/stop", json={})
    assert no_csrf.status_code == 403
    assert sim.snapshot().plugins == ("ros_measure",)


class _Broken(FirmwarePlugin):
    """A script that fails at start."""

    name = "broken_test_script"

    def start(self, gripper: ScriptHost) -> None:
        raise RuntimeError("line 3: attempt to call a nil value")


def test_a_script_failing_at_start_sets_sf_script_failure(sim: LiveSim, api: httpx.Client,
                                                          monkeypatch: pytest.MonkeyPatch) -> None:
    """000 Appendix B D20 SF_SCRIPT_FAILURE; the next started script clears it (device rule)."""
    monkeypatch.setitem(PLUGINS, _Broken.name, _Broken)
    r = api.post("/api/scripting/start", json={"plugin": _Broken.name})
    assert r.status_code == 409
    body = r.json()
    assert "attempt to call a nil value" in body["detail"]
    assert body["script_failure"] and not body["script_running"] and body["running"] == []
    assert SystemFlag.SF_SCRIPT_FAILURE in flags(sim)
    r = api.post("/api/scripting/start", json={"plugin": "umi_measure"})
    assert r.status_code == 200 and not r.json()["script_failure"]


@pytest.mark.browser
def test_scripting_page_starts_and_stops_a_script(sim: LiveSim, page: Any) -> None:
    page.goto(sim.url + "/")
    page.click("nav a[href='/scripting']")
    assert page.inner_text("main h1") == "Scripting"
    assert page.inner_text("#script-running") == "none"
    assert page.inner_text("#flag-script-running") == "clear"
    page.select_option("#script-plugin", "umi_measure")
    page.click("#script-start")
    page.wait_for_function("document.getElementById('flag-script-running').dataset.on === 'true'")
    assert page.inner_text("#script-running") == "umi_measure"
    assert page.inner_text("#script-result") == "OK"
    # the Gripper box shows the same flag from the live update
    page.wait_for_selector("#flag-list li[data-flag='SF_SCRIPT_RUNNING'].on")
    assert sim.snapshot().plugins == ("umi_measure",)
    page.click("#script-stop")
    page.wait_for_function("document.getElementById('flag-script-running').dataset.on === 'false'")
    wait_for(lambda: sim.snapshot().plugins == ())
    assert page.inner_text("#script-running") == "none"
    assert page.inner_text("#flag-script-failure") == "clear"
