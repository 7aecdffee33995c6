"""JSON API of the web interface, over real HTTP on 127.0.0.1: every endpoint, good and bad input.

Status codes (docs/web.md): 200 done, 202 motion started (E_CMD_PENDING), 409 refused by the
device (its status code in the body), 422 invalid input (``errors`` names each field), 403 missing
or wrong CSRF token / foreign Origin, 401 login required, 413 body too large.
"""

from __future__ import annotations

import itertools
import json
import socket
from pathlib import Path

import httpx
import pytest
import websockets.sync.client as ws_client
from pymodbus.client import ModbusTcpClient
from websockets.exceptions import InvalidStatus
from websockets.typing import Origin

from pywsg.fieldbus.image import CmdFlag, OutputImage
from pywsg.protocol import CATALOG, Command, Frame, SystemFlag

from .conftest import LiveSim, client_for, home, read_status, wait_for

PAGES = ["/", "/settings/interface", "/settings/motion", "/diagnosis/log", "/diagnosis/fieldbus", "/scripting",
         "/simulation", "/help"]


def test_every_page_is_served_without_login_on_loopback(sim: LiveSim) -> None:
    with httpx.Client(base_url=sim.url) as c:
        for path in PAGES:
            r = c.get(path)
            assert r.status_code == 200, path
            assert "WSG 50 Control Panel" in r.text
            assert r.headers["content-security-policy"].startswith("default-src 'self'")
            assert 'name="csrf-token"' in r.text


def test_state_has_every_flag_and_units(sim: LiveSim, api: httpx.Client) -> None:
    s = api.get("/api/state").json()
    assert s["state"] in ("IDLE", "POSITIONING", "HOLDING", "ERROR", "NO_PART", "RELEASING", "GRIPPING",
                          "PART_LOST")
    assert isinstance(s["width"], float) and isinstance(s["temperature"], float)
    assert [f["name"] for f in s["flag_list"]][:2] == ["SF_REFERENCED", "SF_MOVING"]
    assert len(s["flag_list"]) == 19  # the screenshot's right column
    assert s["model"] == "wsg50"


def test_info_reports_limits_from_get_system_limits(api: httpx.Client) -> None:
    info = api.get("/api/info").json()
    assert info["model"] == "WSG 50"
    assert info["limits"]["stroke"] == pytest.approx(110.0)
    assert info["simulation"] is True and info["fieldbus"] is True


@pytest.mark.parametrize("path", ["/api/stop", "/api/ack", "/api/fast-stop", "/api/home", "/api/move",
                                  "/api/grip", "/api/release", "/api/settings", "/api/sim/part",
                                  "/api/sim/block", "/api/sim/heat", "/api/sim/fault"])
def test_state_changing_requests_need_the_csrf_token(sim: LiveSim, path: str) -> None:
    with httpx.Client(base_url=sim.url) as c:
        before = sim.snapshot()
        r = c.post(path, json={"width": 50, "speed": 50})
        assert r.status_code == 403
        assert "CSRF" in r.json()["detail"]
        r = c.post(path, json={"width": 50, "speed": 50}, headers={"X-CSRF-Token": "forged"})
        assert r.status_code == 403
        assert sim.snapshot().fast_stop == before.fast_stop


def test_foreign_origin_is_refused(api: httpx.Client) -> None:
    r = api.post("/api/stop", headers={"Origin": "http://evil.example"})
    assert r.status_code == 403
    assert "cross-origin" in r.json()["detail"]


def test_home_move_stop_through_the_binary_protocol(sim: LiveSim, api: httpx.Client) -> None:
    home(sim, api)
    assert sim.snapshot().width == pytest.approx(110.0, abs=0.01)
    r = api.post("/api/move", json={"width": 20, "speed": 20})
    assert r.status_code == 202
    assert r.json()["status"] == "E_CMD_PENDING"
    wait_for(lambda: sim.snapshot().moving)
    r = api.post("/api/stop")
    assert r.status_code == 200 and r.json()["status"] == "E_SUCCESS"
    snap = sim.snapshot()
    assert not snap.moving and snap.flags & SystemFlag.SF_AXIS_STOPPED
    results = api.get("/api/results").json()
    assert any(r["command"] == "PREPOSITION" and r["status"] == "E_CMD_ABORTED" and r["final"] for r in results)


def test_fast_stop_makes_motion_409_until_ack(sim: LiveSim, api: httpx.Client) -> None:
    home(sim, api)
    assert api.post("/api/fast-stop").status_code == 200
    r = api.post("/api/move", json={"width": 50, "speed": 50})
    assert r.status_code == 409
    assert r.json()["status"] == "E_ACCESS_DENIED"
    assert "refused by the device" in r.json()["detail"]
    assert api.post("/api/ack").status_code == 200
    assert api.post("/api/move", json={"width": 50, "speed": 400}).status_code == 202
    wait_for(lambda: abs(sim.snapshot().width - 50) < 0.01 and not sim.snapshot().moving)


@pytest.mark.parametrize(("path", "body", "field"), [
    ("/api/move", {"width": "50", "speed": 50}, "width"),          # string for a number
    ("/api/move", {"width": True, "speed": 50}, "width"),          # bool for a number
    ("/api/move", {"width": 50}, "speed"),                         # missing
    ("/api/move", {"width": 50, "speed": 50, "force": 3}, "force"),  # unknown field
    ("/api/move", {"width": -1, "speed": 50}, "width"),            # below 0
    ("/api/move", {"width": 500, "speed": 50}, "width"),           # beyond the stroke (110 mm)
    ("/api/move", {"width": 50, "speed": 0}, "speed"),             # not positive
    ("/api/move", {"width": 50, "speed": 5000}, "speed"),          # beyond max speed
    ("/api/grip", {"width": 20, "speed": 50, "force": 1000}, "force"),  # beyond overdrive force
    ("/api/grip", {"width": 20, "speed": 50, "force": -5}, "force"),
    ("/api/release", {"width": 200, "speed": 50}, "width"),
    ("/api/home", {"direction": "up"}, "direction"),
    ("/api/home", {"direction": 1}, "direction"),
    ("/api/sim/part", {"width": 0}, "width"),
    ("/api/sim/part", {"width": 20, "stiffness": -1}, "stiffness"),
    ("/api/sim/block", {"width": 999}, "width"),
    ("/api/sim/heat", {"delta_c": 1000}, "delta_c"),
    ("/api/sim/heat", {"delta_c": "hot"}, "delta_c"),
    ("/api/sim/fault", {"kind": "gravity", "on": True}, "kind"),
    ("/api/sim/fault", {"kind": "finger", "on": True, "finger": 3}, "finger"),
    ("/api/sim/fault", {"kind": "power", "on": "yes"}, "on"),
])
def test_bad_input_is_422_naming_the_field(sim: LiveSim, api: httpx.Client, path: str, body: dict[str, object],
                                           field: str) -> None:
    before = sim.snapshot()
    r = api.post(path, json=body)
    assert r.status_code == 422, r.text
    data = r.json()
    assert field in data["errors"], data
    assert data["detail"].startswith("invalid input")
    after = sim.snapshot()
    assert after.target == before.target and after.part == before.part and after.blocked_at == before.blocked_at


def test_non_json_and_nan_bodies_are_422(api: httpx.Client) -> None:
    hdr = {"Content-Type": "application/json"}
    assert api.post("/api/move", content=b"width=5", headers=hdr).status_code == 422
    assert api.post("/api/move", content=b'{"width": NaN, "speed": 5}', headers=hdr).status_code == 422
    assert api.post("/api/move", content=b"[1, 2]", headers=hdr).status_code == 422
    assert api.post("/api/settings", content=b"{oops", headers=hdr).status_code == 422


def test_oversized_body_is_413(api: httpx.Client) -> None:
    r = api.post("/api/settings", content=b"{" + b" " * 70000 + b"}",
                 headers={"Content-Type": "application/json"})
    assert r.status_code == 413


def test_grip_with_force_limit_holds_a_placed_part(sim: LiveSim, api: httpx.Client) -> None:
    home(sim, api)
    assert api.post("/api/sim/part", json={"width": 30}).status_code == 200
    r = api.post("/api/grip", json={"width": 30, "speed": 100, "force": 40})
    assert r.status_code == 202, r.text
    wait_for(lambda: sim.snapshot().gripper_state.name == "HOLDING", 5)
    assert sim.snapshot().force_limit == pytest.approx(40)
    r = api.post("/api/release", json={"width": 60, "speed": 100})
    assert r.status_code == 202
    wait_for(lambda: sim.snapshot().gripper_state.name == "IDLE" and not sim.snapshot().moving, 5)
    assert api.delete("/api/sim/part").status_code == 200
    assert sim.snapshot().part is None


def test_simulation_endpoints_change_the_device(sim: LiveSim, api: httpx.Client) -> None:
    assert api.post("/api/sim/block", json={"width": 30}).status_code == 200
    assert sim.snapshot().blocked_at == pytest.approx(30)
    assert api.delete("/api/sim/block").status_code == 200
    assert sim.snapshot().blocked_at is None
    t0 = sim.snapshot().temperature
    assert api.post("/api/sim/heat", json={"delta_c": 5}).status_code == 200
    assert sim.snapshot().temperature == pytest.approx(t0 + 5, abs=0.5)
    assert api.post("/api/sim/heat", json={"delta_c": -5}).status_code == 200
    r = api.post("/api/sim/fault", json={"kind": "power", "on": True})
    assert r.status_code == 200
    assert "SF_POWER_FAULT" in r.json()["state"]["flag_names"]
    assert api.post("/api/sim/fault", json={"kind": "power", "on": False}).status_code == 200
    assert not sim.snapshot().flags & SystemFlag.SF_POWER_FAULT
    assert api.post("/api/sim/fault", json={"kind": "finger", "finger": 2, "on": True}).status_code == 200
    assert sim.snapshot().flags & SystemFlag.SF_FINGER_FAULT
    assert api.post("/api/sim/fault", json={"kind": "finger", "finger": 2, "on": False}).status_code == 200
    assert api.post("/api/sim/fault", json={"kind": "current", "on": True}).status_code == 200
    assert sim.snapshot().flags & SystemFlag.SF_CURR_FAULT
    assert api.post("/api/sim/fault", json={"kind": "current", "on": False}).status_code == 200
    api.post("/api/ack")


def test_settings_apply_live_and_persist(sim: LiveSim, api: httpx.Client) -> None:
    data = api.get("/api/settings").json()
    groups = {f["name"]: f["group"] for f in data["fields"]}
    assert groups["crc_check"] == "interface" and groups["fast_stop_on_disconnect"] == "interface"
    assert groups["clamping_travel"] == "motion" and groups["model"] == "motion"
    r = api.post("/api/settings", json={"clamping_travel": 7.5, "homing_direction": 2})
    assert r.status_code == 200, r.text
    assert r.json()["changed"] == ["clamping_travel", "homing_direction"]
    assert sim.call(lambda: sim.gripper.settings.clamping_travel) == 7.5
    saved = json.loads(sim.settings_path.read_text())
    assert saved["clamping_travel"] == 7.5 and saved["homing_direction"] == 2
    r = api.post("/api/settings", json={"clamping_travel": 5.0, "homing_direction": 1})
    assert r.status_code == 200
    # Motion Configuration: auto-homing on start, persisted
    assert groups["auto_homing"] == "motion"
    assert api.post("/api/settings", json={"auto_homing": True}).status_code == 200
    assert json.loads(sim.settings_path.read_text())["auto_homing"] is True
    assert api.post("/api/settings", json={"auto_homing": "yes"}).status_code == 422
    assert api.post("/api/settings", json={"auto_homing": False}).status_code == 200


@pytest.mark.parametrize(("body", "field", "words"), [
    ({"clamping_travel": 500}, "clamping_travel", "0..110"),          # out of range (device's check)
    ({"clamping_travel": "5"}, "clamping_travel", "number"),          # wrong type
    ({"crc_check": 0}, "crc_check", "true or false"),
    ({"homing_direction": 3}, "homing_direction", "one of"),
    ({"model": "wsg99"}, "model", "one of"),
    ({"default_acceleration": 1e9}, "default_acceleration", "mm/s"),
    ({"no_such_setting": 1}, "no_such_setting", "unknown"),
    ({"crc_check": None}, "crc_check", "required"),
])
def test_invalid_settings_are_refused_per_field(sim: LiveSim, api: httpx.Client, body: dict[str, object],
                                                field: str, words: str) -> None:
    before = sim.call(lambda: sim.gripper.settings)
    r = api.post("/api/settings", json=body)
    assert r.status_code == 422, r.text
    assert words in r.json()["errors"][field]
    assert sim.call(lambda: sim.gripper.settings) == before


def test_settings_body_must_be_a_nonempty_object(api: httpx.Client) -> None:
    assert api.post("/api/settings", json=[1]).status_code == 422
    assert api.post("/api/settings", json={}).status_code == 422


def test_crc_setting_is_obeyed_over_tcp_at_once(sim: LiveSim, api: httpx.Client) -> None:
    bad = bytearray(Frame(Command.GET_SYSTEM_STATE, CATALOG[Command.GET_SYSTEM_STATE].encode_request(
        flags=0, period_ms=0)).encode())
    bad[-1] ^= 0xFF
    with socket.create_connection(("127.0.0.1", sim.tcp.port), timeout=3) as s:
        s.sendall(bytes(bad))
        assert read_status(s) == "E_CHECKSUM_ERROR"
        assert api.post("/api/settings", json={"crc_check": False}).status_code == 200
        s.sendall(bytes(bad))
        assert read_status(s) == "E_SUCCESS"
        assert api.post("/api/settings", json={"crc_check": True}).status_code == 200
        s.sendall(Frame(Command.DISCONNECT).encode())
        read_status(s)


def test_log_is_incremental_and_validates(sim: LiveSim, api: httpx.Client) -> None:
    data = api.get("/api/log").json()
    assert any("started" in e["message"] for e in data["entries"])
    last = data["last"]
    api.post("/api/fast-stop")
    api.post("/api/ack")
    new = api.get("/api/log", params={"after": last}).json()["entries"]
    messages = [e["message"] for e in new]
    assert any("FAST STOP" in m for m in messages) and "FAST STOP acknowledged" in messages
    assert all(e["seq"] > last for e in new)
    assert new[0]["level"] in ("info", "warning", "error") and new[0]["wall_time"] > 1e9
    assert api.get("/api/log", params={"after": -1}).status_code == 422
    assert api.get("/api/log", params={"limit": 0}).status_code == 422
    assert api.get("/api/log", params={"limit": "many"}).status_code == 422


def test_fieldbus_view_follows_a_modbus_master(sim: LiveSim, api: httpx.Client) -> None:
    home(sim, api)
    fb = api.get("/api/fieldbus").json()
    assert fb["available"] and len(fb["output"]["bytes"]) == 8 and len(fb["input"]["bytes"]) == 12
    image = OutputImage.from_units(CmdFlag.MOVE, width_mm=42.0, speed_mm_s=100.0, force_n=20.0, if_flags=0x20)
    with ModbusTcpClient("127.0.0.1", port=sim.modbus.port) as mb:
        assert not mb.write_registers(0, image.registers()).isError()
        fb = api.get("/api/fieldbus").json()
        out = fb["output"]
        assert out["hex"] == image.pack().hex(" ").upper()
        assert out["bytes"][0]["hex"] == "01h" and out["bytes"][1]["hex"] == "20h"
        regs = {r["name"]: r for r in out["registers"]}
        assert regs["Width"]["text"] == "42.00 mm"
        assert [b["name"] for b in regs["Command Flags"]["bits"] if b["on"]] == ["MOVE"]
        assert [b["name"] for b in regs["User Flags"]["bits"] if b["on"]] == ["IF6"]
        wait_for(lambda: abs(sim.snapshot().width - 42) < 0.01 and not sim.snapshot().moving, 5)
        inp = {r["name"]: r for r in api.get("/api/fieldbus").json()["input"]["registers"]}
        assert inp["Current Opening Width"]["text"] == "42.00 mm"
        assert inp["Error Code"]["text"] == "E_SUCCESS"
        assert "SF_REFERENCED" in inp["System State"]["flags"]
        mb.write_registers(0, OutputImage().registers())


def test_commands_reference_covers_the_catalog(api: httpx.Client) -> None:
    cmds = api.get("/api/commands").json()
    assert [c["id"] for c in cmds] == sorted(CATALOG)
    grip = next(c for c in cmds if c["name"] == "GRIP_PART")
    assert [f["name"] for f in grip["request"]] == ["width", "speed"] and grip["kind"] == "pending"
    page = api.get("/help").text
    for spec in CATALOG.values():
        assert f"id='cmd-{spec.id:02X}'" in page


def test_project_docs_are_served_by_name_only(api: httpx.Client) -> None:
    r = api.get("/docs/architecture.md")
    assert r.status_code == 200 and "pywsg architecture" in r.text
    assert api.get("/docs/..%2Fpyproject.toml").status_code == 404
    assert api.get("/docs/nothing.md").status_code == 404
    assert api.get("/api/openapi.json").json()["info"]["title"] == "pywsg web interface"


def test_websocket_streams_at_about_20_hz(sim: LiveSim) -> None:
    cookie = client_for(sim).cookies.get("wsg_session")
    url = sim.url.replace("http", "ws") + "/ws?fieldbus=1"
    with ws_client.connect(url, additional_headers={"Cookie": f"wsg_session={cookie}"}) as ws:
        msgs = [json.loads(ws.recv(timeout=30)) for _ in range(21)]  # 30 s: generous for a loaded machine
    # the server's own send times: 50 ms apart at least (a loaded machine only stretches them; no upper
    # bound here, that would be a wall-time bound - the recv timeout is the liveness check)
    gaps = sorted(b["t"] - a["t"] for a, b in itertools.pairwise(msgs))
    assert gaps[0] > 0.045 and gaps[len(gaps) // 2] > 0.049, gaps
    assert all(m["type"] == "update" and "width" in m["state"] for m in msgs)
    assert msgs[0]["fieldbus"]["available"] is True


def test_websocket_refuses_a_foreign_origin(sim: LiveSim) -> None:
    url = sim.url.replace("http", "ws") + "/ws"
    with pytest.raises(InvalidStatus) as info:
        ws_client.connect(url, origin=Origin("http://evil.example"))
    assert info.value.response.status_code == 403


async def test_wsg_sim_serves_the_web_interface_with_fieldbus_and_interfaces(tmp_path: Path) -> None:
    """The path ``wsg sim --web-port`` takes: SimServer passes sim_info, the fieldbus controller and
    the settings file to serve_web."""
    from pywsg.server import SimServer

    settings = tmp_path / "s.json"
    async with SimServer(tcp_port=0, udp_port=None, modbus_port=0, web_port=0, settings=settings) as server:
        port = server.grippers[0].web_port
        async with httpx.AsyncClient(base_url=f"http://127.0.0.1:{port}") as c:
            assert "Fieldbus Monitor" in (await c.get("/diagnosis/fieldbus")).text
            assert (await c.get("/api/fieldbus")).json()["available"] is True
            data = (await c.get("/api/settings")).json()
            assert data["interfaces"]["tcp"] == f"tcp://127.0.0.1:{server.tcp_port}"
            assert data["settings_file"] == str(settings)
            token = (await c.get("/api/csrf")).json()["token"]
            r = await c.post("/api/settings", json={"fast_stop_on_disconnect": False},
                             headers={"X-CSRF-Token": token})
            assert r.status_code == 200 and r.json()["saved"] == str(settings)
    assert json.loads(settings.read_text())["fast_stop_on_disconnect"] is False
