"""axe-core finds no WCAG 2.0-2.2 A/AA violation on the Commander page (and its Connect dialog), at phone and
desktop width, in real headless Chromium; the desktop page is the README's screenshot (docs/img/commander.png)."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import pytest

from pywsg.testing.host import SimThread

from ..test_axe import AXE, RUN_AXE
from ..test_browser import shot
from .harness import Cmdr
from .test_commander_browser import DESKTOP, PHONE, connect

pytestmark = pytest.mark.browser


@pytest.fixture(scope="module")
def sim() -> Iterator[SimThread]:
    with SimThread(model="wsg50", tcp_port=0, udp_port=None) as s:
        yield s


@pytest.fixture(scope="module")
def cmdr() -> Iterator[Cmdr]:
    with Cmdr() as c:
        yield c


@pytest.mark.parametrize("viewport", [PHONE, DESKTOP], ids=["phone", "desktop"])
def test_axe_finds_no_wcag_violation(sim: SimThread, cmdr: Cmdr, open_page: Any, viewport: dict[str, int]) -> None:
    if not AXE.exists():
        pytest.fail(f"{AXE} missing: scripts/test.sh installs axe-core from npm (or set PYWSG_AXE_JS)")
    page = open_page(viewport)
    cmdr.http.post("/api/log/clear")  # this page's frames only
    connect(page, cmdr, "tcp", host="127.0.0.1", port=str(sim.g.tcp_port))
    page.fill("#ed-id", "30h")  # Set Acceleration 150 mm/s², as in 000 §2's editor example
    page.fill("#ed-payload", "150.0f")
    page.wait_for_function("(document.getElementById('ed-packet').dataset.wire || '').startsWith('AA AA AA 30 04')")
    page.click("#ed-send")
    page.wait_for_selector("#log-body tr.rx td:text-is('SET_ACCELERATION')")
    page.fill("#conv-bytes", "00 00 16 43")
    page.dispatch_event("#conv-bytes", "input")
    page.add_script_tag(path=str(AXE))
    if viewport is DESKTOP:
        shot(page, "commander", doc="commander.png")
    assert page.evaluate(RUN_AXE) == []
    page.fill("#ed-payload", '0 0 150.0f "x')  # an error shown at its item
    page.wait_for_selector("#ed-payload[aria-invalid=true]")
    assert page.evaluate(RUN_AXE) == []
    page.click("#btn-connect")  # and the Connect dialog
    assert page.evaluate(RUN_AXE) == []
    page.keyboard.press("Escape")
    assert not page.locator("#connect-dialog").is_visible()
