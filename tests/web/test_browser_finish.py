"""The web interface on a phone, across page changes and restarts, in real headless Chromium.

Issue 26: Stop, state and position within reach while scrolling on a phone; plot history and
command results kept across page changes; plots sized to their panel and sharp at 3x; the page
agreeing with the device (overdrive, force range, Ack refused by a fault, stale "not sent", the
Simulation page's part and block); menus (focus leaving closes, arrow keys, inside the window,
scrollable tables focusable, link sizes, the login page on loopback); Escape stops from anywhere and
Stop comes first in the tab order; the menu names of manual 003 §6, figure 1.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest

from .conftest import LiveSim, client_for, home, wait_for
from .test_browser import live, shot

pytestmark = pytest.mark.browser

PHONE = {"viewport": {"width": 390, "height": 844}, "device_scale_factor": 3, "is_mobile": True, "has_touch": True}
SMALL_PHONE = {"viewport": {"width": 360, "height": 740}, "is_mobile": True, "has_touch": True}
LAPTOP = {"viewport": {"width": 1366, "height": 768}}
WIDE = {"viewport": {"width": 1920, "height": 1080}}


def _open(browser: Any, errors: list[str], **kwargs: Any) -> Any:
    context = browser.new_context(bypass_csp=True, **kwargs)
    pg = context.new_page()
    pg.on("pageerror", lambda exc: errors.append(str(exc)))
    pg.set_default_timeout(8000)
    return pg


@pytest.fixture
def pages(browser: Any) -> Iterator[Any]:
    """``pages(**context options)`` opens a page; all are closed at teardown, JavaScript errors fail."""
    errors: list[str] = []
    opened: list[Any] = []

    def make(**kwargs: Any) -> Any:
        pg = _open(browser, errors, **kwargs)
        opened.append(pg)
        return pg

    yield make
    for pg in opened:
        pg.context.close()
    assert not errors, f"JavaScript errors: {errors}"


@pytest.fixture
def fresh_sim(tmp_path: Path) -> Iterator[LiveSim]:
    with LiveSim(tmp_path) as s:
        yield s


def _results(sim: LiveSim) -> list[dict[str, Any]]:
    with httpx.Client(base_url=sim.url, timeout=5) as c:
        return list(c.get("/api/results").json())


def _stops(sim: LiveSim) -> int:
    return sum(r["command"] == "STOP" and r["status"] == "E_SUCCESS" for r in _results(sim))


IN_VIEW = """(sel) => { const el = document.querySelector(sel); const r = el.getBoundingClientRect();
  if (!r.width || r.top < 0 || r.bottom > innerHeight || r.left < 0 || r.right > innerWidth) return false;
  const hit = document.elementFromPoint(r.left + r.width / 2, r.top + r.height / 2);
  return !!hit && (hit === el || el.contains(hit) || hit === el.parentElement); }"""


# -- 1. phone: Stop, state and position within reach -----------------------------------------------

def test_phone_keeps_stop_state_and_position_in_reach_after_move(sim: LiveSim, pages: Any) -> None:
    api = client_for(sim)
    home(sim, api)
    page = pages(**PHONE)
    page.goto(sim.url + "/")
    live(page)
    assert page.evaluate(IN_VIEW, "#btn-stop")
    assert page.locator("#quickbar").is_hidden()  # the Gripper box is in view: no second bar
    page.fill("#form-move [name=width]", "10")
    page.fill("#form-move [name=speed]", "5")  # slow: still moving when Stop is tapped
    page.tap("#form-move button[type=submit]")
    page.wait_for_function("document.querySelector('#form-move output').innerText.startsWith('E_')")
    assert not page.evaluate(IN_VIEW, "#btn-stop")  # the box's Stop is far above ...
    page.wait_for_function(f"({IN_VIEW})('#btn-stop-quick')")  # ... the quick bar's is on screen
    for sel in ("#q-state", "#q-width"):
        page.wait_for_function(f"({IN_VIEW})('{sel}')")
    page.wait_for_function("document.getElementById('q-state').innerText === 'POSITIONING'")
    assert page.inner_text("#q-width").endswith("mm")
    shot(page, "phone-after-move")
    stops = _stops(sim)
    page.tap("#btn-stop-quick")
    wait_for(lambda: _stops(sim) > stops)
    wait_for(lambda: not sim.snapshot().moving)
    api.close()


# -- 2. history across page changes ------------------------------------------------------------------

def test_plot_history_and_results_survive_a_page_change(sim: LiveSim, pages: Any) -> None:
    api = client_for(sim)
    page = pages(**LAPTOP)
    page.goto(sim.url + "/")
    live(page)
    home(sim, api)
    page.wait_for_function("document.querySelectorAll('#results li').length >= 2 && WSG.plots.width.points.length > 20")
    before = page.evaluate("Array.from(document.querySelectorAll('#results li')).map(li => li.innerText)")
    points = page.evaluate("WSG.plots.width.points.length")
    first_t = page.evaluate("WSG.plots.width.points[0][0]")
    page.click("nav a[href='/help']")
    page.wait_for_url(sim.url + "/help")
    api.post("/api/stop")  # a result while the Control Panel is not open
    live(page)
    page.click("nav a[href='/']")
    page.wait_for_url(sim.url + "/")
    page.wait_for_function("WSG.updates > 0")
    # the plot starts with what it had (not empty) and the list with the earlier results
    assert page.evaluate("WSG.plots.width.points[0][0]") == first_t
    assert page.evaluate("WSG.plots.width.points.length") >= points
    page.wait_for_function("Array.from(document.querySelectorAll('#results li'))"
                           ".some(li => li.innerText.includes('STOP'))")
    after = page.evaluate("Array.from(document.querySelectorAll('#results li')).map(li => li.innerText)")
    assert after[-len(before):] == before, (before, after)
    api.close()


# -- 3. plots sized to their panel, sharp at 3x, labels inside --------------------------------------

def test_plots_fill_their_panel_on_a_wide_screen(sim: LiveSim, pages: Any) -> None:
    page = pages(**WIDE)
    page.goto(sim.url + "/")
    live(page)
    used, panel = page.evaluate("""() => { const p = document.querySelector('.plots');
      const w = Array.from(p.querySelectorAll('canvas')).reduce((s, c) => s + c.getBoundingClientRect().width, 0);
      return [w, p.clientWidth]; }""")
    assert used >= 0.9 * panel, (used, panel)


@pytest.mark.parametrize("size", ["phone", "small-phone"])
def test_plots_are_sharp_and_their_labels_legible_on_a_phone(sim: LiveSim, pages: Any, size: str) -> None:
    page = pages(**(PHONE if size == "phone" else SMALL_PHONE))
    page.goto(sim.url + "/")
    live(page)
    page.wait_for_function("WSG.plots.width.labels && WSG.plots.width.labels.length > 0")
    for name in ("width", "force"):
        got = page.evaluate(f"""() => {{ const p = WSG.plots.{name}, c = p.canvas, r = c.getBoundingClientRect();
          return {{backing: c.width, css: r.width, dpr: devicePixelRatio, font: p.ctx.font, labels: p.labels,
                   panel: c.closest('.panel').clientWidth}}; }}""")
        assert abs(got["backing"] - round(got["css"] * got["dpr"])) <= 1, got  # one canvas pixel per screen pixel
        assert got["css"] >= 0.8 * got["panel"], got
        assert int(got["font"].split("px")[0]) >= 12, got  # 12 CSS px: never scaled down
        texts = [lab["text"] for lab in got["labels"]]
        assert "now" in texts, texts
        for lab in got["labels"]:
            assert lab["x0"] >= 0 and lab["x1"] <= got["css"], (lab, got["css"])


# -- 4. the page agrees with the device --------------------------------------------------------------

def test_overdrive_selector_shows_the_device_flag(sim: LiveSim, pages: Any) -> None:
    api = client_for(sim)
    api.post("/api/overdrive", json={"on": False})
    page = pages(**LAPTOP)
    page.goto(sim.url + "/settings/motion")
    live(page)
    page.wait_for_function("document.querySelector('#form-overdrive select').value === 'false'")
    api.post("/api/overdrive", json={"on": True})  # another client switches it
    page.wait_for_function("document.querySelector('#form-overdrive select').value === 'true'")
    api.post("/api/overdrive", json={"on": False})
    page.wait_for_function("document.querySelector('#form-overdrive select').value === 'false'")
    api.close()


def test_force_refusal_names_the_range_the_hint_shows(sim: LiveSim, pages: Any) -> None:
    page = pages(**LAPTOP)
    page.goto(sim.url + "/")
    live(page)
    page.wait_for_selector("#form-grip-force-range")
    hint = page.inner_text("#form-grip-force-range")  # "allowed 5 … 120 N"
    low, high = hint.removeprefix("allowed ").removesuffix(" N").split(" … ")
    page.fill("#form-grip [name=force]", "500")
    page.click("#form-grip button[type=submit]")
    page.wait_for_function("document.querySelector('#form-grip .field-error[data-for=force]').innerText !== ''")
    assert page.inner_text("#form-grip .field-error[data-for=force]") == f"must be between {low} and {high} N"


def test_ack_refused_by_a_fault_names_the_fault(fresh_sim: LiveSim, pages: Any) -> None:
    sim = fresh_sim
    api = client_for(sim)
    page = pages(**LAPTOP)
    page.goto(sim.url + "/simulation")
    live(page)
    assert api.post("/api/sim/fault", json={"kind": "power", "on": True}).status_code == 200
    page.wait_for_function("document.body.dataset.state !== undefined && "
                           "WSG.last.state.flag_names.includes('SF_POWER_FAULT')")
    page.click("#btn-ack")
    page.wait_for_function("document.getElementById('banner').innerText.includes('Ack failed')")
    text = page.inner_text("#banner")
    assert "Power Fault" in text and "Access denied" not in text, text
    api.close()


def test_not_sent_message_goes_when_the_gripper_is_back(fresh_sim: LiveSim, pages: Any) -> None:
    sim = fresh_sim
    page = pages(**LAPTOP)
    page.goto(sim.url + "/")
    live(page)
    port = sim.stop_web()
    page.wait_for_function("document.body.classList.contains('stale')")
    page.click("#form-move button[type=submit]")
    page.wait_for_function("document.querySelector('#form-move output').innerText.includes('not sent')")
    sim.start_web(port)
    page.wait_for_function("WSG.live && !document.body.classList.contains('stale')", timeout=15000)
    page.wait_for_function("document.querySelector('#form-move output').innerText === ''")


def test_simulation_page_shows_the_part_and_the_block(sim: LiveSim, pages: Any) -> None:
    api = client_for(sim)
    page = pages(**LAPTOP)
    try:
        assert api.post("/api/sim/part", json={"width": 22.0}).status_code == 200
        page.goto(sim.url + "/simulation")
        live(page)
        page.wait_for_function(
            "document.getElementById('world-part').innerText === '22.00 mm wide, gripped from outside'")
        page.fill("#form-part [name=width]", "40")
        page.check("#form-part [name=inside]")  # issue 24 item 7: a ring, gripped from inside
        page.click("#form-part button[type=submit]")
        page.wait_for_function(
            "document.getElementById('world-part').innerText === '40.00 mm wide, a ring gripped from inside'")
        assert sim.call(lambda: sim.gripper.obstacles["part"].blocks) == 1
        assert page.inner_text("#world-block") == "none"
        page.fill("#form-block [name=width]", "30")
        page.click("#form-block button[type=submit]")  # set on this page: shown at once
        page.wait_for_function("document.getElementById('world-block').innerText === 'at 30.00 mm'")
        api.delete("/api/sim/part")  # changed elsewhere: shown within a second
        page.wait_for_function("document.getElementById('world-part').innerText === 'none'")
    finally:
        api.delete("/api/sim/part")
        api.delete("/api/sim/block")
        api.close()


# -- 5. menus --------------------------------------------------------------------------------------

def test_menu_keys_arrows_and_leaving_with_tab(sim: LiveSim, pages: Any) -> None:
    page = pages(**LAPTOP)
    page.goto(sim.url + "/")
    live(page)
    button = page.locator("button[aria-controls='menu-diagnosis']")
    button.focus()
    page.keyboard.press("ArrowDown")  # opens the menu on its first item
    assert button.get_attribute("aria-expanded") == "true"
    active = "document.activeElement.getAttribute('href')"
    assert page.evaluate(active) == "/diagnosis/log"
    page.keyboard.press("ArrowDown")
    assert page.evaluate(active) == "/diagnosis/fieldbus"
    page.keyboard.press("ArrowDown")  # wraps
    assert page.evaluate(active) == "/diagnosis/log"
    page.keyboard.press("ArrowUp")
    assert page.evaluate(active) == "/diagnosis/fieldbus"
    page.keyboard.press("Tab")  # focus leaves the menu: it closes
    assert button.get_attribute("aria-expanded") == "false"
    assert page.locator("#menu-diagnosis").is_hidden()


@pytest.mark.parametrize("size", ["phone", "small-phone"])
def test_menus_stay_inside_a_phone_screen(sim: LiveSim, pages: Any, size: str) -> None:
    page = pages(**(PHONE if size == "phone" else SMALL_PHONE))
    page.goto(sim.url + "/")
    live(page)
    # every menu button at the right edge of its row, as on a phone whose fonts wrap the menu bar so
    page.evaluate("document.querySelector('ul.nav').style.justifyContent = 'flex-end'")
    for button in page.locator("ul.nav button[aria-controls]").all():
        button.tap()
        menu = page.locator("#" + str(button.get_attribute("aria-controls")))
        assert menu.is_visible()
        right = page.evaluate("(el) => el.getBoundingClientRect().right", menu.element_handle())
        assert right <= page.evaluate("innerWidth"), right
        assert page.evaluate("document.documentElement.scrollWidth") <= page.evaluate("innerWidth")
        button.tap()


def test_scrolling_register_tables_take_focus_on_a_small_phone(sim: LiveSim, pages: Any) -> None:
    page = pages(**SMALL_PHONE)
    page.goto(sim.url + "/diagnosis/fieldbus")
    live(page)
    page.wait_for_selector("#fb-input tbody tr")
    page.wait_for_function("""Array.from(document.querySelectorAll('main table'))
      .filter(t => t.scrollWidth > t.clientWidth + 1).length > 0""")  # the check below has something to check
    page.wait_for_function("""Array.from(document.querySelectorAll('main table'))
      .filter(t => t.scrollWidth > t.clientWidth + 1).every(t => t.tabIndex === 0)""")


def test_help_links_are_touch_targets(sim: LiveSim, pages: Any) -> None:
    page = pages(**PHONE)
    page.goto(sim.url + "/help")
    live(page)
    small = page.evaluate("""Array.from(document.querySelectorAll('main li > a'))
      .filter(a => a.getBoundingClientRect().height < 24).map(a => a.innerText)""")
    assert page.locator("main li > a").count() > 40
    assert not small, small


def test_login_page_on_loopback_has_no_password_field_and_a_way_back(sim: LiveSim, pages: Any) -> None:
    page = pages(**PHONE)
    page.goto(sim.url + "/login?next=/diagnosis/log")
    assert "no login needed" in page.inner_text("body")
    assert page.locator("input[type=password]").count() == 0
    page.tap("#login-back")
    page.wait_for_url(sim.url + "/diagnosis/log")


# -- 6. Stop from anywhere, first in the tab order ------------------------------------------------------

def test_escape_stops_from_any_field_and_first_closes_a_menu(sim: LiveSim, pages: Any) -> None:
    api = client_for(sim)
    home(sim, api)
    page = pages(**LAPTOP)
    page.goto(sim.url + "/")
    live(page)
    assert page.get_attribute("#btn-stop", "aria-keyshortcuts") == "Escape"
    api.post("/api/move", json={"width": 5.0 if sim.snapshot().width > 50 else 100.0, "speed": 5.0})
    wait_for(lambda: sim.snapshot().moving)
    menu = page.locator("button[aria-controls='menu-diagnosis']")
    menu.click()
    stops = _stops(sim)
    page.keyboard.press("Escape")  # closes the menu only
    assert menu.get_attribute("aria-expanded") == "false"
    assert sim.snapshot().moving and _stops(sim) == stops
    page.focus("#form-release [name=speed]")
    page.keyboard.press("Escape")
    wait_for(lambda: _stops(sim) > stops)
    wait_for(lambda: not sim.snapshot().moving)
    api.close()


def test_stop_comes_before_the_page_in_the_tab_order_on_a_phone(sim: LiveSim, pages: Any) -> None:
    page = pages(**PHONE)
    page.goto(sim.url + "/")
    live(page)
    seen: list[str] = []
    for _ in range(40):
        page.keyboard.press("Tab")
        where = page.evaluate("document.activeElement.id || document.activeElement.tagName")
        if page.evaluate("!!document.activeElement.closest('main')"):
            seen.append("main")
        if where == "btn-stop":
            break
        seen.append(where)
    else:
        raise AssertionError(f"Stop not reached: {seen}")
    assert "main" not in seen, seen


# -- 7. names from manual 003 §6, figure 1 ---------------------------------------------------------------

def test_menu_and_header_follow_figure_1_of_the_fieldbus_manual(sim: LiveSim, pages: Any) -> None:
    api = client_for(sim)
    page = pages(**LAPTOP)
    try:
        page.goto(sim.url + "/")
        live(page)
        menu = page.evaluate("Array.from(document.querySelectorAll('ul.nav > li > a, ul.nav > li > button'))"
                             ".map(e => e.textContent.trim())")
        # figure 1's "Settings | Diagnostics | Scripting | Motion | Help", named as the manuals' menu paths do
        order = [m for m in menu if m in ("Settings", "Diagnosis", "Scripting", "Motion", "Help")]
        assert order == ["Settings", "Diagnosis", "Scripting", "Motion", "Help"], menu
        page.wait_for_function("document.getElementById('id-location').innerText === 'n/a'")
        assert "Location: n/a, Contact: n/a" in page.inner_text("header")
        r = api.post("/api/settings", json={"location": "cell 7", "contact": "line@example.com"})
        assert r.status_code == 200, r.text
        page.reload()
        page.wait_for_function("document.getElementById('id-location').innerText === 'cell 7'")
        assert "Location: cell 7, Contact: line@example.com" in page.inner_text("header")
    finally:
        api.post("/api/settings", json={"location": None, "contact": None})
        api.close()


def test_fidelity_records_where_the_manuals_name_things_differently() -> None:
    text = (Path(__file__).resolve().parents[2] / "docs" / "fidelity.md").read_text()
    for words in ("### Menu names", "Diagnosis -> Fieldbus Monitor", "### GRIP or GRASP", "### Header",
                  "### Device tag after a restart"):
        assert words in text, words
