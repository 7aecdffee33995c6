"""The web interface as a product (issue 15), in real headless Chromium.

A restart of the simulator with the page open, then Stop; the server gone (stale values, commands
that fail with a message); the Move result race; every control clickable at 390×844, 360×740 and
1366×768 and 1920×1080 (Playwright's actionability checks); keyboard-only navigation to every page and to Stop;
the identity header; the Motion page's commands (overdrive and tare through their forms); a script
error shown as SF_SCRIPT_FAILURE; contrast and touch-target sizes.
"""

from __future__ import annotations

import dataclasses
import itertools
import socket
import struct
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest

from pywsg.device import FirmwarePlugin, Session
from pywsg.device.fingers import FMF_ZERO_DRIFT_N
from pywsg.device.plugins import ScriptHost
from pywsg.protocol import CATALOG, Command, Frame, Status, SystemFlag

from .conftest import LiveSim, client_for, home, read_status, submit_form, wait_for
from .test_browser import PAGES, live, shot

pytestmark = pytest.mark.browser

VIEWPORTS = {"phone": (390, 844), "small-phone": (360, 740), "laptop": (1366, 768), "wide": (1920, 1080)}


@pytest.fixture
def fresh_sim(tmp_path: Path) -> Iterator[LiveSim]:
    with LiveSim(tmp_path) as s:
        yield s


def _page(browser: Any, size: tuple[int, int], errors: list[str]) -> Any:
    context = browser.new_context(viewport={"width": size[0], "height": size[1]}, bypass_csp=True)
    pg = context.new_page()
    pg.on("pageerror", lambda exc: errors.append(str(exc)))
    pg.set_default_timeout(5000)
    return pg


@pytest.fixture
def phone(browser: Any) -> Iterator[Any]:
    errors: list[str] = []
    pg = _page(browser, VIEWPORTS["phone"], errors)
    yield pg
    pg.context.close()
    assert not errors, f"JavaScript errors: {errors}"


def _results(sim: LiveSim) -> list[dict[str, Any]]:
    with httpx.Client(base_url=sim.url, timeout=5) as c:
        return list(c.get("/api/results").json())


def test_stop_works_after_a_restart_with_the_page_open(fresh_sim: LiveSim, page: Any) -> None:
    """Issue 15 item 3: the page reconnects with a new CSRF token; Stop then reaches the device."""
    sim = fresh_sim
    page.goto(sim.url + "/")
    live(page)
    port = sim.stop_web()
    page.wait_for_function("document.body.classList.contains('stale')")
    sim.start_web(port)  # a new app: the page's session and CSRF token are unknown to it
    # 1) Stop clicked at once, before the WebSocket is back: a refused token is renewed and Stop resent
    page.click("#btn-stop")
    wait_for(lambda: any(r["command"] == "STOP" and r["status"] == "E_SUCCESS" for r in _results(sim)))
    # the page clears the banner when Stop's HTTP answer reaches it, a moment after the device has the Stop
    page.wait_for_function("document.getElementById('banner').hidden", timeout=30_000)
    # 2) after the reconnect the page has the new token; Stop works, and so does a motion
    page.wait_for_function("!document.body.classList.contains('stale') && WSG.live")
    assert page.inner_text("#ws-text") == "live"
    stops = sum(r["command"] == "STOP" for r in _results(sim))
    page.click("#btn-stop")
    wait_for(lambda: sum(r["command"] == "STOP" and r["status"] == "E_SUCCESS" for r in _results(sim)) > stops)
    page.click("#form-home button[type=submit]")
    page.wait_for_function("document.querySelector('#form-home output').innerText.startsWith('E_')")
    assert "403" not in page.inner_text("#form-home output")


def test_server_down_shows_stale_values_and_commands_fail_with_a_message(fresh_sim: LiveSim, page: Any) -> None:
    """Issue 15 item 4: values marked stale, a click gets a message, no uncaught 'Failed to fetch'."""
    sim = fresh_sim
    page.goto(sim.url + "/")
    live(page)
    assert "stale" not in (page.get_attribute("body", "class") or "")
    port = sim.stop_web()
    page.wait_for_function("document.body.classList.contains('stale')")
    assert "stale" in page.inner_text("#ws-text")
    # the side box's values are drawn as stale (struck through, grey), not in full colour
    style = page.evaluate("getComputedStyle(document.querySelector('#g-state')).textDecorationLine")
    assert "line-through" in style
    assert "stale" in page.inner_text("#banner")
    page.click("#btn-stop")
    page.wait_for_function("document.querySelector('#banner').innerText.includes('Stop failed')")
    assert "no connection" in page.inner_text("#banner")
    page.click("#form-move button[type=submit]")
    page.wait_for_function("document.querySelector('#form-move output').innerText.includes('not sent')")
    assert page.get_attribute("#form-move output", "class") == "result bad"
    shot(page, "server-down")
    sim.start_web(port)
    page.wait_for_function("WSG.live && !document.body.classList.contains('stale')", timeout=10000)
    # the page fixture asserts that no uncaught JavaScript error happened


def test_move_result_is_never_stuck_at_pending(sim: LiveSim, page: Any) -> None:
    """Issue 15 item 5: 30 zero-length moves; each result beside the form ends at E_SUCCESS."""
    api = client_for(sim)
    home(sim, api)
    width = sim.snapshot().width
    page.goto(sim.url + "/")
    live(page)
    page.fill("#form-move input[name=width]", f"{width:.3f}")
    for _ in range(30):
        page.evaluate("document.querySelector('#form-move output').textContent = ''")
        page.click("#form-move button[type=submit]")
        page.wait_for_function(
            "['E_SUCCESS'].includes(document.querySelector('#form-move output').innerText)", timeout=3000)
    api.close()


def _controls_not_clickable(page: Any) -> list[str]:
    """Visible controls of the main column and the Gripper box that fail Playwright's click checks."""
    bad = []
    # (disabled check boxes are displays: the Fieldbus Monitor's bits)
    loc = page.locator("main button, main input:not([disabled]), main select, main a, #gripper-box button, "
                       "nav button, nav > ul > li > a")
    for i in range(loc.count()):
        el = loc.nth(i)
        if not el.is_visible():
            continue
        try:
            el.click(trial=True, timeout=1500)
        except Exception as exc:
            bad.append(f"{el.evaluate('e => e.outerHTML.slice(0, 80)')}: {str(exc).splitlines()[0]}")
    return bad


@pytest.mark.parametrize("viewport", list(VIEWPORTS))
def test_every_control_is_clickable_and_nothing_overflows(sim: LiveSim, browser: Any, viewport: str) -> None:
    """Issue 15 item 1: a responsive layout 360..1920 px (360, 390, 1366 and 1920 wide): nothing wider than
    the window, and at phone width no box covers a control."""
    errors: list[str] = []
    page = _page(browser, VIEWPORTS[viewport], errors)
    failures: dict[str, list[str]] = {}
    for path in PAGES:
        page.goto(sim.url + path)
        live(page)
        if path.startswith("/settings"):
            page.wait_for_function("document.getElementById('settings-form').dataset.loaded === '1'")
        bad = _controls_not_clickable(page)
        if bad:
            failures[path] = bad
        overflow = page.evaluate("document.documentElement.scrollWidth - window.innerWidth")
        assert overflow <= 1, (path, overflow)
        if viewport == "phone":
            shot(page, "phone" + path.replace("/", "_"), "control-panel-phone.png" if path == "/" else None)
        elif viewport == "wide" and path == "/":
            shot(page, "wide-control-panel")
    page.context.close()
    assert not failures, failures
    assert not errors


def _tab_to(page: Any, selector: str, limit: int = 60) -> None:
    for _ in range(limit):
        page.keyboard.press("Tab")
        if page.evaluate("(s) => document.activeElement && document.activeElement.matches(s)", selector):
            return
    raise AssertionError(f"{selector} not reached with Tab")


def test_keyboard_reaches_stop_first_and_every_page(sim: LiveSim, page: Any) -> None:
    """Issue 15 item 2: a skip link to Stop; menus per the WAI-ARIA disclosure pattern."""
    page.goto(sim.url + "/diagnosis/log")
    live(page)
    page.keyboard.press("Tab")
    assert page.evaluate("document.activeElement.id") == "skip-stop"
    assert page.locator("#skip-stop").is_visible()  # shown when focused
    page.keyboard.press("Enter")
    assert page.evaluate("document.activeElement.id") == "btn-stop"
    stops = sum(r["command"] == "STOP" for r in _results(sim))
    page.keyboard.press("Enter")
    wait_for(lambda: sum(r["command"] == "STOP" for r in _results(sim)) > stops)
    page.wait_for_function("document.getElementById('announce').innerText.length > 0")
    for path, title in PAGES.items():
        page.goto(sim.url + "/")
        menu = page.locator(f"ul.nav li:has(a[href='{path}']) > button")
        if menu.count():
            button_id = menu.get_attribute("aria-controls")
            _tab_to(page, f"button[aria-controls='{button_id}']")
            assert menu.get_attribute("aria-expanded") == "false"
            page.keyboard.press("Enter")
            assert menu.get_attribute("aria-expanded") == "true"
            page.keyboard.press("Escape")  # closes and returns focus to the button
            assert menu.get_attribute("aria-expanded") == "false"
            assert page.evaluate("document.activeElement.getAttribute('aria-controls')") == button_id
            page.keyboard.press("Space")
            assert page.locator(f"#{button_id}").is_visible()
        _tab_to(page, f"nav a[href='{path}']")
        page.keyboard.press("Enter")
        page.wait_for_url(sim.url + path)
        assert page.inner_text("main h1") == title


def _tcp_request(sim: LiveSim, command: Command, **values: Any) -> str:
    with socket.create_connection(("127.0.0.1", sim.tcp.port), timeout=5) as s:
        s.sendall(Frame(int(command), CATALOG[command].encode_request(values)).encode())
        status = read_status(s)
        s.sendall(Frame(Command.DISCONNECT).encode())  # announced: no FAST STOP (000 §1.4.2)
        read_status(s)
        return status


def test_identity_header_shows_the_device_and_the_tag_from_any_client(sim: LiveSim, page: Any) -> None:
    """Issue 15 item 7: model, firmware, serial, hw revision; a tag set with 51h over TCP shows up."""
    page.goto(sim.url + "/settings/interface")
    live(page)
    page.wait_for_function("document.getElementById('id-fw').innerText !== '–'")
    assert page.inner_text("#id-fw") == "4.0.2"
    assert page.inner_text("#id-serial") == str(sim.call(lambda: sim.gripper.serial_number))
    assert page.inner_text("#id-hw") == "1"
    assert page.inner_text("#model-title") == "WSG 50 Control Panel"
    assert _tcp_request(sim, Command.SET_DEVICE_TAG, tag="cell 4 left") == "E_SUCCESS"
    page.wait_for_function("document.getElementById('id-tag').innerText === 'cell 4 left'", timeout=8000)
    # and set from the page: any client reads it with 52h
    page.fill("#tag-input", "cell 4 right")
    page.click("#form-tag button[type=submit]")
    page.wait_for_function("document.getElementById('id-tag').innerText === 'cell 4 right'")
    with socket.create_connection(("127.0.0.1", sim.tcp.port), timeout=5) as s:
        s.sendall(Frame(int(Command.GET_DEVICE_TAG), b"").encode())
        head = s.recv(6)
        size = struct.unpack_from("<H", head, 4)[0]
        rest = b""
        while len(rest) < size + 2:
            rest += s.recv(size + 2 - len(rest))
        s.sendall(Frame(Command.DISCONNECT).encode())
        read_status(s)
    _, values = CATALOG[Command.GET_DEVICE_TAG].decode_reply(rest[:size])
    assert values["tag"] == "cell 4 right"
    page.fill("#tag-input", "x" * 64 + "y")  # maxlength stops typing; a longer value by API is 422
    assert len(page.input_value("#tag-input")) == 64
    shot(page, "identity-header")


def test_motion_page_soft_limits_statistics_and_jog(sim: LiveSim, page: Any) -> None:
    """Issue 15 item 10: soft limits (34h–36h), statistics (42h), jog held and released."""
    api = client_for(sim)
    assert not sim.snapshot().flags & SystemFlag.SF_FAST_STOP
    home(sim, api)
    api.post("/api/move", json={"width": 50, "speed": 200})
    wait_for(lambda: not sim.snapshot().moving and abs(sim.snapshot().width - 50) < 0.01)
    page.goto(sim.url + "/settings/motion")
    live(page)
    page.wait_for_function("document.getElementById('stat-total').innerText !== '–'")
    submit_form(page, "#form-soft-limits", minus="10", plus="90")
    page.wait_for_function("document.getElementById('soft-now').innerText === '10.00 mm … 90.00 mm'")
    assert api.get("/api/soft-limits").json() == {"minus": 10.0, "plus": 90.0}
    submit_form(page, "#form-soft-limits", minus="80", plus="20")
    page.wait_for_function("document.querySelector('#form-soft-limits .field-error[data-for=plus]').innerText")
    page.click("#form-soft-limits button.delete")
    page.wait_for_function("document.getElementById('soft-now').innerText === 'none set'")
    # jog: held → the fingers open; released → they stop
    page.fill("#form-jog input[name=speed]", "20")
    before = sim.snapshot().width
    page.hover("#jog-open")
    page.mouse.down()
    wait_for(lambda: sim.snapshot().width > before + 1)
    page.mouse.up()
    wait_for(lambda: not sim.snapshot().moving)
    stopped = sim.snapshot().width
    page.wait_for_timeout(300)
    assert sim.snapshot().width == pytest.approx(stopped, abs=0.01)
    assert stopped < 110
    page.click("#form-stats button[type=submit]")
    page.wait_for_function("document.querySelector('#form-stats output').innerText === 'E_SUCCESS'")
    shot(page, "motion-configuration", "motion-configuration.png")
    api.close()


def test_motion_page_overdrive_form_switches_the_device(sim: LiveSim, page: Any) -> None:
    """Issue 15 item 10: the 37h form (000 §3.3.8) turns overdrive on and off; the device and the flag list follow."""
    assert not sim.snapshot().overdrive
    page.goto(sim.url + "/settings/motion")
    live(page)
    page.select_option("#form-overdrive select[name=on]", "true")
    page.click("#form-overdrive button[type=submit]")
    page.wait_for_function("document.querySelector('#form-overdrive output').innerText === 'E_SUCCESS'")
    assert sim.snapshot().overdrive and sim.snapshot().flags & SystemFlag.SF_OVERDRIVE_MODE
    page.wait_for_selector("#flag-list li[data-flag=SF_OVERDRIVE_MODE].on")
    page.evaluate("document.querySelector('#form-overdrive output').textContent = ''")
    page.select_option("#form-overdrive select[name=on]", "false")
    page.click("#form-overdrive button[type=submit]")
    page.wait_for_function("document.querySelector('#form-overdrive output').innerText === 'E_SUCCESS'")
    assert not sim.snapshot().overdrive and not sim.snapshot().flags & SystemFlag.SF_OVERDRIVE_MODE
    page.wait_for_selector("#flag-list li[data-flag=SF_OVERDRIVE_MODE]:not(.on)")


def test_motion_page_tare_form_zeroes_the_force_sensor(fresh_sim: LiveSim, page: Any) -> None:
    """Issue 15 item 10: the 38h form (000 §3.3.9): generic fingers answer E_NOT_AVAILABLE beside the form;
    with force-measuring fingers (FMF) the device takes the sensor's zero offset as its tare."""
    sim = fresh_sim
    page.goto(sim.url + "/settings/motion")
    live(page)
    page.click("#form-tare button[type=submit]")
    page.wait_for_function("document.querySelector('#form-tare output').innerText.startsWith('E_NOT_AVAILABLE')")
    assert page.get_attribute("#form-tare output", "class") == "result bad"
    settings = sim.call(lambda: sim.gripper.settings)
    sim.call(sim.gripper.apply_settings, dataclasses.replace(settings, finger1="fmf"))  # a power-cycle
    assert sim.call(lambda: sim.gripper.fingers[0].tare_offset) == 0.0
    page.reload()
    live(page)
    page.click("#form-tare button[type=submit]")
    page.wait_for_function("document.querySelector('#form-tare output').innerText === 'E_SUCCESS'")
    assert sim.call(lambda: sim.gripper.fingers[0].tare_offset) == pytest.approx(FMF_ZERO_DRIFT_N)
    assert sim.call(lambda: sim.gripper.fingers[0].fmf_force(0.0)) == pytest.approx(0.0)


class _CrashingScript(FirmwarePlugin):
    """An on-board script with a bug: its command C1h divides by zero."""

    name = "crashing"
    commands = (0xC1,)

    def handle(self, gripper: ScriptHost, session: Session, command_id: int, payload: bytes,
               now: float) -> Frame:
        return Frame.reply(command_id, Status.E_SUCCESS, bytes([1 // len(payload)]))


def test_scripting_page_shows_a_script_failure(fresh_sim: LiveSim, page: Any) -> None:
    """Issue 15 item 8: a script that fails is aborted and SF_SCRIPT_FAILURE shows "on" (000 App. B D20);
    starting a script from the page resets it ("The flag is reset whenever a script is started")."""
    sim = fresh_sim
    page.goto(sim.url + "/scripting")
    live(page)
    page.wait_for_function("document.getElementById('script-flag-failure').innerText === 'off'")
    sim.call(sim.gripper.load_plugin, _CrashingScript())
    page.wait_for_function("document.getElementById('script-running').innerText === 'crashing'")
    assert page.inner_text("#script-flag-running") == "on"
    with socket.create_connection(("127.0.0.1", sim.tcp.port), timeout=5) as s:
        s.sendall(Frame(0xC1, b"").encode())  # the request that hits the bug
        assert read_status(s) == "E_CMD_FAILED"
        s.sendall(Frame(Command.DISCONNECT).encode())
        read_status(s)
    assert sim.snapshot().flags & SystemFlag.SF_SCRIPT_FAILURE
    page.wait_for_function("document.getElementById('script-flag-failure').innerText === 'on'")
    assert page.inner_text("#script-flag-running") == "off"
    assert page.inner_text("#script-running") == "none"
    assert page.locator("#flag-list li[data-flag=SF_SCRIPT_FAILURE].on").count() == 1
    shot(page, "scripting-failure")
    page.select_option("#script-name", "if_of_mirror")
    page.click("#form-script button[type=submit]")
    page.wait_for_function("document.getElementById('script-flag-failure').innerText === 'off'")
    assert page.inner_text("#script-running") == "if_of_mirror"
    assert not sim.snapshot().flags & SystemFlag.SF_SCRIPT_FAILURE


CONTRAST_JS = """
() => {
  function rgb(c) { const m = c.match(/[\\d.]+/g).map(Number); return m; }
  function lum(c) {
    const [r, g, b] = rgb(c).slice(0, 3).map(v => {
      v /= 255; return v <= 0.03928 ? v / 12.92 : ((v + 0.055) / 1.055) ** 2.4;
    });
    return 0.2126 * r + 0.7152 * g + 0.0722 * b;
  }
  function bg(el) {
    for (let e = el; e; e = e.parentElement) {
      const c = getComputedStyle(e).backgroundColor;
      if (c && !c.startsWith('rgba(0, 0, 0, 0)') && c !== 'transparent') return c;
    }
    return 'rgb(255, 255, 255)';
  }
  const bad = [];
  for (const el of document.querySelectorAll('body *')) {
    if (!el.offsetParent && el.tagName !== 'BODY') continue;
    const own = Array.from(el.childNodes).some(n => n.nodeType === 3 && n.textContent.trim());
    if (!own || el.closest('button:disabled, .sr-only, .skip, canvas')) continue;
    const s = getComputedStyle(el);
    if (s.visibility === 'hidden') continue;
    const a = lum(s.color), b = lum(bg(el));
    const ratio = (Math.max(a, b) + 0.05) / (Math.min(a, b) + 0.05);
    const large = parseFloat(s.fontSize) >= 24 || (parseFloat(s.fontSize) >= 18.66 && Number(s.fontWeight) >= 700);
    if (ratio < (large ? 3 : 4.5)) {
      bad.push(el.tagName + ' "' + el.textContent.trim().slice(0, 30) + '" ' + ratio.toFixed(2));
    }
  }
  return bad;
}
"""

# A control's hit area: the element, or for a check box the label around it (a click there toggles
# it, see test_check_boxes_toggle_from_the_edge_of_their_label). Disabled boxes are displays (the
# Fieldbus Monitor's bits), not targets. Height and width must both be at least 40 px.
TARGETS_JS = """
() => Array.from(document.querySelectorAll(
    'main button, main select, main input:not([disabled]), #gripper-box button, nav button, nav > ul > li > a'))
  .filter(e => e.offsetParent)
  .map(e => {
    const target = (e.type === 'checkbox' && e.closest('label')) || e;
    const r = target.getBoundingClientRect();
    return [e.outerHTML.slice(0, 60), Math.min(r.height, r.width)];
  })
  .filter(x => x[1] < 40)
"""

CHECKBOXES_JS = """
() => Array.from(document.querySelectorAll('main input[type=checkbox]:not([disabled])'))
  .filter(e => e.offsetParent).map(e => e.id)
"""


@pytest.mark.parametrize("viewport", ["phone", "laptop"])
def test_contrast_and_touch_targets(sim: LiveSim, browser: Any, viewport: str) -> None:
    """Issue 15 item 14: text at WCAG AA contrast (4.5:1, large 3:1), controls (check boxes too) ≥ 40 × 40 px."""
    errors: list[str] = []
    page = _page(browser, VIEWPORTS[viewport], errors)
    for path in PAGES:
        page.goto(sim.url + path)
        live(page)
        if path.startswith("/settings"):
            page.wait_for_function("document.getElementById('settings-form').dataset.loaded === '1'")
        assert page.evaluate(CONTRAST_JS) == [], path
        assert page.evaluate(TARGETS_JS) == [], path
        assert page.locator("[aria-live]").count() >= 1
    page.goto(sim.url + "/")
    live(page)
    page.wait_for_timeout(200)
    label = page.get_attribute("#plot-width", "aria-label") or ""
    assert label.startswith("Width over the last 30 s"), label
    page.context.close()
    assert not errors


@pytest.mark.parametrize("viewport", ["phone", "laptop"])
def test_check_boxes_toggle_from_the_edge_of_their_label(sim: LiveSim, browser: Any, viewport: str) -> None:
    """Issue 15 item 14: a check box's 40 px hit area is real: a tap 2 px inside its label's corner toggles it."""
    errors: list[str] = []
    page = _page(browser, VIEWPORTS[viewport], errors)
    seen: set[str] = set()
    for path in PAGES:
        page.goto(sim.url + path)
        live(page)
        if path.startswith("/settings"):
            page.wait_for_function("document.getElementById('settings-form').dataset.loaded === '1'")
        for box in page.evaluate(CHECKBOXES_JS):
            seen.add(box)
            before = page.is_checked(f"#{box}")
            for corner in ("top-left", "bottom-right"):
                # the whole label in view (a phone scrolls a wide table sideways), then its rectangle
                r = page.evaluate(f"""(() => {{
                    const label = document.getElementById('{box}').closest('label');
                    label.scrollIntoView({{block: 'center', inline: 'center'}});
                    return JSON.parse(JSON.stringify(label.getBoundingClientRect())); }})()""")
                assert min(r["width"], r["height"]) >= 40, (path, box, r)
                x, y = (r["x"] + 2, r["y"] + 2) if corner == "top-left" else (r["right"] - 2, r["bottom"] - 2)
                hit = page.evaluate(f"(document.elementFromPoint({x}, {y}) || {{outerHTML: 'nothing'}})"
                                    ".outerHTML.slice(0, 100)")
                assert hit.startswith('<label class="check"') or hit.startswith(f'<input type="checkbox" id="{box}"') \
                    or f'id="{box}"' in hit, (path, box, corner, hit, r)
                page.mouse.click(x, y)
                assert page.is_checked(f"#{box}") != before, (path, box, corner)
                page.mouse.click(x, y)
                assert page.is_checked(f"#{box}") == before, (path, box, corner)
    page.context.close()
    # the Command Interface page's protocol options and DHCP, the System Log's "follow"
    assert {"set-crc_check", "if-dhcp", "log-follow"} <= seen, seen
    assert not errors


def test_plots_show_no_position_before_homing_and_round_nonnegative_ticks(fresh_sim: LiveSim, page: Any) -> None:
    """Issue 15 item 6 (plots): no 0.00 mm line while the position is [n/a]; ticks 0, 0.5, 1 … not -0.08."""
    sim = fresh_sim
    assert not sim.snapshot().referenced
    page.goto(sim.url + "/")
    live(page)
    page.wait_for_timeout(300)
    assert page.inner_text("#g-width") == "[n/a]" and page.inner_text("#width-now") == "[n/a]"
    assert page.evaluate("WSG.plots.width.points.every(p => p[1] === null)")
    for plot in ("width", "force"):
        ticks = page.evaluate(f"WSG.plots.{plot}.ticks")
        assert ticks and min(ticks) >= 0, ticks
        steps = {round(b - a, 6) for a, b in itertools.pairwise(ticks)}
        assert len(steps) == 1 and next(iter(steps)) in (0.1, 0.2, 0.25, 0.5, 1, 2, 5, 10, 20, 50), ticks
    api = client_for(sim)
    home(sim, api)
    page.wait_for_function("WSG.plots.width.points.some(p => p[1] !== null)")
    # the axis is rescaled on the next animation frame after the first real width arrives
    page.wait_for_function("Math.max(...WSG.plots.width.ticks) >= 110")
    ticks = page.evaluate("WSG.plots.width.ticks")
    assert min(ticks) >= 0 and max(ticks) >= 110, ticks
    api.close()


def test_fast_stop_is_announced_to_screen_readers(fresh_sim: LiveSim, page: Any) -> None:
    """Issue 15 item 14: state and FAST STOP changes reach the aria-live region."""
    sim = fresh_sim
    page.goto(sim.url + "/")
    live(page)
    assert page.get_attribute("#announce", "aria-live") == "polite"
    api = client_for(sim)
    assert api.post("/api/fast-stop").status_code == 200
    page.wait_for_function("document.getElementById('announce').innerText.includes('FAST STOP active')")
    assert api.post("/api/ack").status_code == 200
    page.wait_for_function("!document.getElementById('announce').innerText.includes('FAST STOP')")
    api.close()


def test_error_after_fast_stop_and_ack_says_how_it_clears(fresh_sim: LiveSim, page: Any) -> None:
    """Issue 15 item 6 / 001 §41h: grip state ERROR "remains until the next motion command"; after Ack
    the page says so instead of showing an ERROR with no flag set; a motion command clears it."""
    sim = fresh_sim
    page.goto(sim.url + "/")
    live(page)
    api = client_for(sim)
    home(sim, api)
    assert api.post("/api/fast-stop").status_code == 200
    page.wait_for_function("document.getElementById('g-state').innerText == 'ERROR'")
    assert "acknowledge" in page.inner_text("#g-state-note")
    assert api.post("/api/ack").status_code == 200
    page.wait_for_function("document.getElementById('g-state-note').innerText.includes('next motion command')")
    assert page.is_visible("#g-state-note")
    r = api.post("/api/move", json={"width": 50.0, "speed": 100.0})
    assert r.status_code in (200, 202), r.text  # 202: E_CMD_PENDING, the motion runs
    page.wait_for_function("document.getElementById('g-state').innerText != 'ERROR'")
    assert not page.is_visible("#g-state-note")
    api.close()
