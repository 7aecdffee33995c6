"""axe-core (the npm package, installed by scripts/test.sh) finds no WCAG 2.0-2.2 A/AA (2.2: target size)
violation on any page, at phone and laptop width, in real headless Chromium."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import pytest

from .conftest import LiveSim
from .test_browser import PAGES, live

pytestmark = pytest.mark.browser

ROOT = Path(__file__).resolve().parents[2]
AXE = Path(os.environ.get("PYWSG_AXE_JS", ROOT / ".venv" / "axe" / "node_modules" / "axe-core" / "axe.min.js"))

RUN_AXE = """async () => {
  const tags = ['wcag2a', 'wcag2aa', 'wcag21a', 'wcag21aa', 'wcag22aa'];
  const r = await axe.run(document, {runOnly: {type: 'tag', values: tags}});
  return r.violations.map(v => `${v.id} (${v.impact}): ${v.nodes.slice(0, 3).map(n => n.target.join(' ')).join(', ')}`);
}"""


@pytest.mark.parametrize("size", [(390, 844), (1366, 768)], ids=["phone", "laptop"])
def test_axe_finds_no_wcag_violation_on_any_page(sim: LiveSim, browser: Any, size: tuple[int, int]) -> None:
    if not AXE.exists():
        pytest.fail(f"{AXE} missing: scripts/test.sh installs axe-core from npm (or set PYWSG_AXE_JS)")
    context = browser.new_context(viewport={"width": size[0], "height": size[1]}, bypass_csp=True)
    page = context.new_page()
    page.set_default_timeout(10000)
    found: dict[str, list[str]] = {}
    try:
        for path in PAGES:
            page.goto(sim.url + path)
            live(page)
            page.add_script_tag(path=str(AXE))
            violations = page.evaluate(RUN_AXE)
            if violations:
                found[path] = violations
    finally:
        context.close()
    assert not found, f"axe-core {size[0]}x{size[1]}: {found}"


def test_axe_run_reports_a_planted_violation(sim: LiveSim, browser: Any) -> None:
    """The check above can fail: an image without a text alternative planted on the page is reported."""
    if not AXE.exists():
        pytest.fail(f"{AXE} missing: scripts/test.sh installs axe-core from npm (or set PYWSG_AXE_JS)")
    context = browser.new_context(bypass_csp=True)
    page = context.new_page()
    try:
        page.goto(sim.url + "/")
        live(page)
        page.evaluate("document.querySelector('main').appendChild(document.createElement('img'))")
        page.add_script_tag(path=str(AXE))
        assert any(v.startswith("image-alt") for v in page.evaluate(RUN_AXE))
    finally:
        context.close()
