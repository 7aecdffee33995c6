"""Identity, Motion page commands, the System Log's details and export, error pages (issue 15).

Items 7 (identity: 50h, 51h/52h), 10 (42h statistics, 34h–36h soft limits, 37h overdrive, 38h
tare, jog), 12 (which setting changed from what to what, ISO time with date, export, folded
repeats) and 13 (HTML 404 and 429 pages, power-cycle confirmation, ranges before a submit).
"""

from __future__ import annotations

import csv
import io
import json
import re
import socket
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest

from pywsg.protocol import Command, Frame, SystemFlag

from .conftest import LiveSim, home, read_status, wait_for
from .test_security import PASSWORD, login

ISO = re.compile(r"^\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d\.\d{3}Z$")


def test_identity_reports_system_info_and_tag(sim: LiveSim, api: httpx.Client) -> None:
    """000 §3.5 (50h Get System Info, 51h/52h device tag)."""
    d = api.get("/api/identity").json()
    assert d["model"] == "WSG 50" and d["firmware"] == "4.0.2" and d["hw_revision"] == 1
    assert d["serial"] == sim.call(lambda: sim.gripper.serial_number)
    r = api.post("/api/tag", json={"tag": "cell 4 left"})
    assert r.status_code == 200, r.text
    assert api.get("/api/identity").json()["tag"] == "cell 4 left"
    r = api.post("/api/tag", json={"tag": "x" * 65})
    assert r.status_code == 422 and "tag" in r.json()["errors"]
    assert api.get("/api/identity").json()["tag"] == "cell 4 left"


def test_statistics_count_grips_and_reset(sim: LiveSim, api: httpx.Client) -> None:
    """000 §3.4.3 (42h Get Gripping Statistics; D0 resets after reading)."""
    home(sim, api)
    before = api.get("/api/statistics").json()["total"]
    assert api.post("/api/grip", json={"width": 20, "speed": 100}).status_code == 202  # no part: NO_PART
    wait_for(lambda: not sim.snapshot().moving)
    stats = api.get("/api/statistics").json()
    assert stats["total"] == before + 1 and stats["no_part"] >= 1
    r = api.post("/api/statistics/reset")
    assert r.status_code == 200 and r.json()["values"]["total"] == before + 1  # read, then reset
    assert api.get("/api/statistics").json() == {"total": 0, "no_part": 0, "lost_part": 0}
    api.post("/api/release", json={"width": 60, "speed": 100})
    wait_for(lambda: not sim.snapshot().moving)


def test_soft_limits_set_read_clear_and_refuse(sim: LiveSim, api: httpx.Client) -> None:
    """000 §3.3.5–3.3.7 (34h/35h/36h soft limits)."""
    assert api.post("/api/soft-limits", json={"minus": 5, "plus": 100}).status_code == 200
    assert api.get("/api/soft-limits").json() == {"minus": 5.0, "plus": 100.0}
    r = api.post("/api/soft-limits", json={"minus": 50, "plus": 40})
    assert r.status_code == 422 and "plus" in r.json()["errors"]
    r = api.post("/api/soft-limits", json={"minus": 5, "plus": 500})
    assert r.status_code == 422 and "width" in r.json()["errors"]
    assert api.delete("/api/soft-limits").status_code == 200
    assert api.get("/api/soft-limits").json() == {"minus": None, "plus": None}


def test_overdrive_tare_and_jog(sim: LiveSim, api: httpx.Client) -> None:
    """000 §3.3.8 (37h overdrive), §3.3.9 (38h tare); jog as the fieldbus JOG (003 §5)."""
    home(sim, api)
    assert api.post("/api/overdrive", json={"on": True}).status_code == 200
    assert sim.snapshot().flags & SystemFlag.SF_OVERDRIVE_MODE
    assert api.post("/api/overdrive", json={"on": False}).status_code == 200
    assert not sim.snapshot().flags & SystemFlag.SF_OVERDRIVE_MODE
    r = api.post("/api/tare")  # generic fingers have no force sensor to tare: the device says so
    assert r.status_code == 409 and r.json()["status"] == "E_NOT_AVAILABLE"
    assert api.post("/api/move", json={"width": 50, "speed": 200}).status_code == 202
    wait_for(lambda: not sim.snapshot().moving)
    assert api.post("/api/jog", json={"direction": "close", "speed": 20}).status_code == 200
    wait_for(lambda: sim.snapshot().width < 49)
    assert api.post("/api/jog", json={"direction": "stop"}).status_code == 200
    wait_for(lambda: not sim.snapshot().moving)
    assert api.post("/api/jog", json={"direction": "sideways"}).status_code == 422
    assert api.post("/api/jog", json={"direction": "open", "speed": 1e6}).status_code == 422


def test_log_names_the_changed_setting_from_what_to_what(sim: LiveSim, api: httpx.Client) -> None:
    last = api.get("/api/log").json()["last"]
    old = sim.call(lambda: sim.gripper.settings.clamping_travel)
    assert api.post("/api/settings", json={"clamping_travel": old + 1.5}).status_code == 200
    messages = [e["message"] for e in api.get(f"/api/log?after={last}").json()["entries"]]
    assert f"setting clamping_travel changed from {json.dumps(old)} to {json.dumps(old + 1.5)} mm " \
           "(web interface)" in messages, messages
    assert api.post("/api/settings", json={"clamping_travel": old}).status_code == 200


def test_log_export_as_csv_and_json_lines(api: httpx.Client) -> None:
    r = api.get("/api/log/export")
    assert r.status_code == 200 and r.headers["content-type"].startswith("text/csv")
    assert re.match(r'attachment; filename="wsg-system-log-\d{8}T\d{6}Z\.csv"', r.headers["content-disposition"])
    rows = list(csv.reader(io.StringIO(r.text)))
    assert rows[0] == ["seq", "time_utc", "level", "message"] and len(rows) > 1
    assert all(ISO.match(row[1]) for row in rows[1:]), rows[:3]
    r = api.get("/api/log/export?format=json")
    lines = [json.loads(line) for line in r.text.splitlines()]
    assert lines and all(ISO.match(e["iso_time"]) and "message" in e for e in lines)
    assert api.get("/api/log/export?format=xml").status_code == 422


def test_unknown_page_is_an_html_page_and_unknown_api_is_json(sim: LiveSim) -> None:
    with httpx.Client(base_url=sim.url, timeout=5, headers={"Accept": "text/html"}) as c:
        r = c.get("/no/such/page")
        assert r.status_code == 404 and r.headers["content-type"].startswith("text/html")
        assert "There is no page /no/such/page." in r.text and "ul class='nav'" in r.text
        assert c.get("/docs/nothing.md").headers["content-type"].startswith("text/html")
        r = c.get("/api/no-such-thing")
        assert r.status_code == 404 and r.json()["detail"] == "Not Found"
    with httpx.Client(base_url=sim.url, timeout=5) as c:  # a script (no text/html): JSON
        assert c.get("/no/such/page").json()["detail"] == "Not Found"


@pytest.fixture
def lockable(tmp_path: Path) -> Iterator[LiveSim]:
    with LiveSim(tmp_path, host="0.0.0.0", password=PASSWORD) as s:
        yield s


def test_login_lockout_is_an_html_page(lockable: LiveSim) -> None:
    with httpx.Client(base_url=lockable.url, timeout=5) as c:
        for _ in range(10):
            assert login(c, "wrong").status_code == 401
        r = login(c)
        assert r.status_code == 429 and r.headers["content-type"].startswith("text/html")
        assert "locked for a minute" in r.text and "<form" in r.text


@pytest.mark.browser
def test_power_cycle_asks_first_and_ranges_show_before_submit(sim: LiveSim, page: Any) -> None:
    page.goto(sim.url + "/")
    page.wait_for_function("document.querySelector('#form-move .range')")
    assert page.inner_text("#form-move-width-range") == "allowed 0 … 110 mm"
    assert page.get_attribute("#form-move input[name=width]", "max") == "110"
    page.goto(sim.url + "/settings/motion")
    page.wait_for_function("document.getElementById('settings-form').dataset.loaded === '1'")
    before = sim.call(lambda: sim.gripper.settings.serial_number)
    dialogs: list[str] = []

    def answer(dialog: Any, accept: bool) -> None:
        dialogs.append(dialog.message)
        dialog.accept() if accept else dialog.dismiss()

    page.once("dialog", lambda d: answer(d, False))
    page.fill("#set-serial_number", "4711")
    page.click("#settings-save")
    page.wait_for_function("document.getElementById('settings-result').innerText === 'not applied'")
    assert "homing is lost" in dialogs[0] and "serial_number" in dialogs[0]
    assert sim.call(lambda: sim.gripper.settings.serial_number) == before
    page.once("dialog", lambda d: answer(d, True))
    page.click("#settings-save")
    page.wait_for_function("document.getElementById('settings-result').innerText.startsWith('Applied')")
    assert str(sim.call(lambda: sim.gripper.settings.serial_number)) == "4711"
    page.once("dialog", lambda d: answer(d, True))
    page.fill("#set-serial_number", "" if before is None else str(before))
    page.click("#settings-save")
    page.wait_for_function("document.getElementById('settings-result').innerText.startsWith('Applied')")


@pytest.mark.browser
def test_log_page_shows_iso_dates_and_folds_repeated_disconnects(sim: LiveSim, page: Any) -> None:
    page.goto(sim.url + "/diagnosis/log")
    page.wait_for_function("window.WSG && WSG.updates > 2")
    for _ in range(5):
        with socket.create_connection(("127.0.0.1", sim.tcp.port), timeout=5) as s:
            s.sendall(Frame(Command.DISCONNECT).encode())
            read_status(s)
    page.wait_for_function("document.querySelector('#log-table tbody tr:last-child').dataset.count === '5'")
    last = page.locator("#log-table tbody tr:last-child td")
    assert "disconnect announced" in last.nth(3).inner_text() and "(×5)" in last.nth(3).inner_text()
    assert re.match(r"^\d{4}-\d\d-\d\d \d\d:\d\d:\d\d\.\d{3}$", last.nth(1).inner_text())


def test_docs_are_rendered_pages_with_their_images_and_downloads(api: httpx.Client) -> None:
    """Issue 15 item 11: Markdown as pages (raw HTML escaped), images served, honest downloads."""
    r = api.get("/docs/web.md")
    assert r.status_code == 200 and r.headers["content-type"].startswith("text/html")
    assert "<h1>The web interface</h1>" in r.text and "<table>" in r.text
    assert '<img src="img/control-panel.png"' in r.text
    img = api.get("/docs/img/control-panel.png")
    assert img.status_code == 200 and img.content[:8] == b"\x89PNG\r\n\x1a\n"
    assert api.get("/docs/img/..%2F..%2Fpyproject.toml").status_code == 404
    raw = api.get("/docs/raw/web.md")
    assert raw.headers["content-type"].startswith("text/markdown") and raw.text.startswith("# The web interface")
    ref = api.get("/downloads/command-reference.html")
    assert "attachment" in ref.headers["content-disposition"] and "25h Grip Part" in ref.text
    rows = list(csv.reader(io.StringIO(api.get("/downloads/fieldbus-register-map.csv").text)))
    assert rows[0][:4] == ["image", "byte_offset", "size_bytes", "modbus_register"]
    width = next(row for row in rows if row[0].startswith("output") and row[4] == "Width")
    assert width[1:4] == ["2", "2", "1"]  # bytes 2..3 = holding register 1 (003 §4.1.1)


@pytest.mark.browser
def test_doc_page_shows_its_screenshots(sim: LiveSim, page: Any) -> None:
    page.goto(sim.url + "/help")
    page.click("#doc-links a[href='/docs/web.md']")
    page.wait_for_function("Array.from(document.images).length > 0 && "
                           "Array.from(document.images).every(i => i.complete && i.naturalWidth > 0)")
    assert page.inner_text("main h1") == "The web interface"


def test_scripting_start_stop_and_flags(sim: LiveSim, api: httpx.Client) -> None:
    """Issue 15 item 8: which script runs, start/stop it, SF_SCRIPT_RUNNING (000 §3.4.1 flag table)."""
    d = api.post("/api/script/stop").json()
    assert d["running"] == [] and not d["script_running"] and "if_of_mirror" in d["available"]
    d = api.post("/api/script/start", json={"name": "if_of_mirror"}).json()
    assert d["running"] == ["if_of_mirror"] and d["script_running"] and not d["script_failure"]
    assert sim.snapshot().flags & SystemFlag.SF_SCRIPT_RUNNING
    r = api.post("/api/script/start", json={"name": "nope"})
    assert r.status_code == 422 and "unknown script" in r.json()["errors"]["name"]
    assert api.get("/api/script").json()["running"] == ["if_of_mirror"]  # a refused start changes nothing
    d = api.post("/api/script/stop").json()
    assert d["running"] == [] and not sim.snapshot().flags & SystemFlag.SF_SCRIPT_RUNNING


@pytest.mark.browser
def test_scripting_page_shows_the_running_script_live(sim: LiveSim, page: Any, api: httpx.Client) -> None:
    page.goto(sim.url + "/scripting")
    page.wait_for_function("document.getElementById('script-name').options.length > 0")
    page.select_option("#script-name", "if_of_mirror")
    page.click("#form-script button[type=submit]")
    page.wait_for_function("document.getElementById('script-flag-running').innerText === 'on'")
    assert page.inner_text("#script-running") == "if_of_mirror"
    page.click("#script-stop")
    page.wait_for_function("document.getElementById('script-flag-running').innerText === 'off'")
    assert page.inner_text("#script-running") == "none"
