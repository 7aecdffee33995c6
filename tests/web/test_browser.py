"""The web interface in real headless Chromium (Debian's chromium, driven by Playwright).

Screenshots go to test-artifacts/web/; the Control Panel and Fieldbus Monitor shots are also
copied to docs/img/ for the README.
"""

from __future__ import annotations

import os
import re
import shutil
import socket
import time
from typing import Any

import httpx
import pytest
from pymodbus.client import ModbusTcpClient

from pywsg.fieldbus.image import CmdFlag, OutputImage
from pywsg.protocol import CATALOG, Command, Frame

from .conftest import ARTIFACTS, DOC_IMAGES, LiveSim, client_for, home, read_status, record_doc_image, wait_for

pytestmark = pytest.mark.browser

PAGES = {
    "/": "Control Panel", "/settings/interface": "Command Interface", "/settings/motion": "Motion Configuration",
    "/diagnosis/log": "System Log", "/diagnosis/fieldbus": "Fieldbus Monitor", "/scripting": "Scripting",
    "/simulation": "Simulation",
    "/help": "Documentation",
}


def shot(page: Any, name: str, doc: str | None = None) -> None:
    """Screenshot the whole page to test-artifacts/web/``name``.png; with PYWSG_UPDATE_DOC_IMAGES=1
    also to docs/img/``doc``, recording the pywsg version the page's header shows in the manifest."""
    path = ARTIFACTS / f"{name}.png"
    update_docs = doc is not None and bool(os.environ.get("PYWSG_UPDATE_DOC_IMAGES"))
    if update_docs:
        page.evaluate("window.scrollTo(0, 0)")  # the sticky Gripper box at the top, as a reader first sees it
    page.screenshot(path=str(path), full_page=True, timeout=30000)  # the Help page is long: seconds on a busy machine
    if doc is not None and update_docs:
        # refresh the README's screenshots only on request: a test run leaves the tree clean
        DOC_IMAGES.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(path, DOC_IMAGES / doc)
        shown = re.search(r"pywsg (\S+)", page.inner_text("header"))
        assert shown, "the header names no pywsg version"
        record_doc_image(doc, shown.group(1))


def live(page: Any) -> None:
    """Wait for the WebSocket to deliver a few updates."""
    page.wait_for_function("window.WSG && WSG.updates > 2")


@pytest.fixture
def api(sim: LiveSim) -> Any:
    c = client_for(sim)
    yield c
    c.close()


def test_every_page_opens_and_goes_live(sim: LiveSim, page: Any) -> None:
    for path, title in PAGES.items():
        page.goto(sim.url + path)
        assert page.inner_text("main h1") == title
        live(page)
        assert page.inner_text("#ws-text") == "live"
        assert page.locator("#flag-list li").count() == 19
        shot(page, "page" + path.replace("/", "_"))
    # menu: the Diagnosis drop-down (003 §6: "Diagnosis -> Fieldbus Monitor") leads to the Fieldbus Monitor
    page.goto(sim.url + "/")
    page.hover("text=Diagnosis")
    page.click("a[href='/diagnosis/fieldbus']")
    assert page.inner_text("main h1") == "Fieldbus Monitor"


def _watch(page: Any, until: str, timeout: float = 10.0) -> list[tuple[str, str, str]]:
    """(position, speed, state) of the side box every 40 ms until the position reads ``until``."""
    seen: list[tuple[str, str, str]] = []
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        # one evaluate reads all three in the same JS task: no WebSocket update can land in between
        w, v, st = page.evaluate(
            "['#g-width', '#g-speed', '#g-state'].map(id => document.querySelector(id).innerText)")
        seen.append((w, v, st))
        if seen[-1][0] == until and seen[-1][2] == "IDLE":
            break
        page.wait_for_timeout(40)
    return seen


def test_home_from_the_control_panel_and_watch_the_width_live(sim: LiveSim, page: Any, api: httpx.Client) -> None:
    # start from closed fingers so that homing (positive direction) has a long way to go
    home(sim, api)
    api.post("/api/move", json={"width": 0, "speed": 400})
    wait_for(lambda: sim.snapshot().width < 0.01 and not sim.snapshot().moving)
    page.goto(sim.url + "/")
    live(page)
    assert page.inner_text("#g-width") == "0.00 mm"
    page.select_option("#form-home select[name=direction]", "positive")
    page.click("#form-home button[type=submit]")
    seen = _watch(page, "110.00 mm")
    assert seen[-1][0] == "110.00 mm"
    during = [s for s in seen if s[2] == "POSITIONING"]
    assert during, seen
    # while homing the position is unknown (as on the real panel) but the fingers' speed shows live
    assert {s[0] for s in during} == {"[n/a]"}
    assert any(float(s[1].split()[0]) > 1 for s in during), during
    page.wait_for_function("document.querySelector('#results').innerText.includes('HOMING E_CMD_PENDING')")
    page.wait_for_function("document.querySelector('#results').innerText.includes('HOMING E_SUCCESS')")
    # the final reply has replaced E_CMD_PENDING beside the form
    page.wait_for_function("document.querySelector('#form-home output').innerText == 'E_SUCCESS'")
    assert page.locator("#flag-list li[data-flag=SF_REFERENCED]").get_attribute("class") == "on"
    # now referenced: a move shows the width changing live, step by step
    page.fill("#form-move input[name=width]", "40")
    page.fill("#form-move input[name=speed]", "100")
    page.click("#form-move button[type=submit]")
    seen = _watch(page, "40.00 mm")
    assert seen[-1][0] == "40.00 mm"
    widths = [float(s[0].split()[0]) for s in seen]
    assert len({w for w in widths if 40.0 < w < 110.0}) >= 3, widths
    assert widths == sorted(widths, reverse=True)  # monotonic closing, sampled live
    assert page.evaluate("WSG.plots.width.points.length") > 10
    page.wait_for_timeout(200)
    shot(page, "control-panel-after-move")


def test_disable_crc_check_in_settings_then_a_bad_crc_frame_runs(sim: LiveSim, page: Any) -> None:
    bad = bytearray(Frame(Command.GET_SYSTEM_STATE, CATALOG[Command.GET_SYSTEM_STATE].encode_request(
        flags=0, period_ms=0)).encode())
    bad[-2] ^= 0x5A
    with socket.create_connection(("127.0.0.1", sim.tcp.port), timeout=3) as s:
        s.sendall(bytes(bad))
        assert read_status(s) == "E_CHECKSUM_ERROR"
        page.goto(sim.url + "/settings/interface")
        page.wait_for_selector("#set-crc_check")
        assert page.is_checked("#set-crc_check")
        assert "Serving now" in page.inner_text("main")  # sim_info: interfaces and ports
        page.uncheck("#set-crc_check")
        page.click("#settings-save")
        page.wait_for_function("document.querySelector('#settings-result').innerText.startsWith('Applied')")
        assert "saved" in page.inner_text("#settings-result")
        shot(page, "settings-crc-off")
        s.sendall(bytes(bad))
        assert read_status(s) == "E_SUCCESS"  # executed despite the wrong CRC
        page.check("#set-crc_check")
        page.click("#settings-save")
        page.wait_for_function("document.querySelector('#settings-result').innerText.startsWith('Applied')")
        s.sendall(bytes(bad))
        assert read_status(s) == "E_CHECKSUM_ERROR"
        s.sendall(Frame(Command.DISCONNECT).encode())
        read_status(s)


def test_invalid_setting_is_refused_beside_the_field(sim: LiveSim, page: Any) -> None:
    page.goto(sim.url + "/settings/motion")
    page.wait_for_selector("#set-clamping_travel")
    page.fill("#set-clamping_travel", "500")
    page.click("#settings-save")
    err = page.locator(".field-error[data-for=clamping_travel]")
    err.wait_for()
    page.wait_for_function("document.querySelector('.field-error[data-for=clamping_travel]').innerText != ''")
    assert "0..110" in err.inner_text()
    assert "invalid" in (page.get_attribute("#set-clamping_travel", "class") or "")
    assert "Not applied" in page.inner_text("#settings-result")
    shot(page, "settings-invalid")
    assert sim.call(lambda: sim.gripper.settings.clamping_travel) == 5.0


def test_inject_a_part_and_grip_it_to_holding(sim: LiveSim, page: Any, api: httpx.Client) -> None:
    home(sim, api)
    page.goto(sim.url + "/simulation")
    live(page)
    page.fill("#form-part input[name=width]", "25")
    page.click("#form-part button[type=submit]")
    page.wait_for_function("document.querySelector('#form-part output').innerText.includes('placed')")
    assert sim.snapshot().part == pytest.approx(25)
    page.click("a[href='/']")
    live(page)
    page.fill("#form-grip input[name=width]", "25")
    page.fill("#form-grip input[name=speed]", "200")
    page.fill("#form-grip input[name=force]", "30")
    page.click("#form-grip button[type=submit]")
    page.wait_for_function("document.querySelector('#g-state').innerText == 'HOLDING'", timeout=8000)
    # the final reply replaces E_CMD_PENDING beside the form
    page.wait_for_function("document.querySelector('#form-grip output.result').innerText == 'E_SUCCESS'")
    page.wait_for_timeout(300)  # a little more plot
    assert float(page.inner_text("#g-force").split()[0]) > 0
    shot(page, "control-panel-holding", doc="control-panel.png")
    # out-of-range input is refused beside the field
    page.fill("#form-grip input[name=width]", "900")
    page.click("#form-grip button[type=submit]")
    page.wait_for_function("document.querySelector('#form-grip .field-error[data-for=width]').innerText != ''")
    assert "between 0 and 110" in page.inner_text("#form-grip .field-error[data-for=width]")
    api.post("/api/release", json={"width": 60, "speed": 400})
    wait_for(lambda: not sim.snapshot().moving)
    api.delete("/api/sim/part")


STATE_SELECTOR = "#fb-bus td[data-row='Interface state']"
STATE = f'document.querySelector("{STATE_SELECTOR}")'


def test_fieldbus_monitor_shows_a_modbus_move_live(sim: LiveSim, page: Any, api: httpx.Client) -> None:
    home(sim, api)
    page.goto(sim.url + "/diagnosis/fieldbus")
    page.wait_for_selector("#fb-output tr[data-index='7']")
    # 003 §6 Interface state: no master yet (item 9 of issue 15 replaced the constant "Online")
    page.wait_for_function(f"{STATE} && {STATE}.textContent.startsWith('Waiting')")
    assert page.locator("#fb-output tbody tr").count() == 8
    assert page.locator("#fb-input tbody tr").count() == 12
    image = OutputImage.from_units(CmdFlag.MOVE, width_mm=30.0, speed_mm_s=40.0, force_n=25.0, if_flags=0x40)
    with ModbusTcpClient("127.0.0.1", port=sim.modbus.port) as mb:
        assert not mb.write_registers(0, image.registers()).isError()
        page.wait_for_function("document.querySelector('#fb-output tr[data-index=\"0\"] td.hex').innerText == '01h'")
        assert page.inner_text(STATE_SELECTOR).startswith("Online: 1 master connected")
        assert page.inner_text("#fb-output tr[data-index='1'] td.hex") == "40h"
        assert page.inner_text("#fb-output td[data-register='Width']") == "30.00 mm"
        assert page.inner_text("#fb-output td[data-register='Speed']") == "40.00 mm/s"
        move = page.locator("#fb-output td[data-register='Command Flags'] label.bit.on")
        assert move.all_inner_texts() == [" MOVE"] or [t.strip() for t in move.all_inner_texts()] == ["MOVE"]
        # the input side follows the motion: POSITIONING while moving, then the new width
        page.wait_for_function(
            "document.querySelector('#fb-input td[data-register=\"Current Opening Width\"]').innerText"
            " == '30.00 mm'", timeout=8000)
        page.wait_for_function(
            "[...document.querySelectorAll('#fb-input td[data-register=\"Gripping State\"] label.bit.on')]"
            ".map(e => e.innerText.trim()).join() == 'IDLE'")
        assert page.inner_text("#fb-input td[data-register='Error Code']") == "E_SUCCESS"
        shot(page, "fieldbus-monitor-move", doc="fieldbus-monitor.png")
        mb.write_registers(0, OutputImage().registers())


def test_system_log_shows_fast_stop_raised_and_acknowledged(sim: LiveSim, page: Any, api: httpx.Client) -> None:
    page.goto(sim.url + "/diagnosis/log")
    live(page)
    assert "started" in page.inner_text("#log-table")
    api.post("/api/fast-stop")
    page.wait_for_function("document.querySelector('#log-table').innerText.includes('FAST STOP')")
    assert page.locator("#flag-list li[data-flag=SF_FAST_STOP].on").count() == 1
    page.click("#btn-ack")  # the side box's Ack button acknowledges it
    page.wait_for_function("document.querySelector('#log-table').innerText.includes('FAST STOP acknowledged')")
    page.wait_for_function("document.querySelectorAll('#flag-list li[data-flag=SF_FAST_STOP].on').length == 0")
    page.fill("#log-filter", "acknowledged")
    assert page.locator("#log-table tbody tr:not([hidden])").count() >= 1
    shot(page, "system-log")


def test_help_lists_docs_and_the_generated_command_reference(sim: LiveSim, page: Any) -> None:
    page.goto(sim.url + "/help")
    assert page.locator("section.cmd").count() == len(CATALOG)
    assert "25h Grip Part" in page.inner_text("#cmd-25 h3")
    assert "E_CMD_PENDING" in page.inner_text("#cmd-25")
    page.click("#doc-links a[href='/docs/architecture.md']")
    assert "pywsg architecture" in page.content()


def test_stop_button_stops_a_motion(sim: LiveSim, page: Any, api: httpx.Client) -> None:
    home(sim, api)
    page.goto(sim.url + "/")
    live(page)
    page.fill("#form-move input[name=width]", "0")
    page.fill("#form-move input[name=speed]", "10")
    page.click("#form-move button[type=submit]")
    page.wait_for_function("document.querySelector('#flag-list li[data-flag=SF_MOVING]').className == 'on'")
    page.click("#btn-stop")
    page.wait_for_function("document.querySelector('#flag-list li[data-flag=SF_AXIS_STOPPED]').className == 'on'")
    assert not sim.snapshot().moving
    assert sim.snapshot().width > 50


