"""Docs and menu names a new user reads (issue 34 items 5 and 10): true to the package and to the manuals."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from pywsg.fieldbus import descriptions
from pywsg.web.pages import nav

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"


def menus(html: str) -> dict[str, dict[str, str]]:
    """The drop-down menus of the menu bar: {menu title: {item label: href}}."""
    return {title: dict((label, href) for href, label in re.findall(r"<a href='([^']*)'[^>]*>([^<]*)</a>", items))
            for title, items in re.findall(r"<button[^>]*>([^<]*)</button><ul[^>]*>(.*?)</ul>", html)}


@pytest.mark.parametrize(("path", "href"), [
    ("Settings -> Command Interface", "/settings/interface"),        # 000 §1.4.1, §1.4.2
    ("Settings -> Motion Configuration", "/settings/motion"),        # 003 §4 (homing)
    ("Diagnosis -> Fieldbus Monitor", "/diagnosis/fieldbus"),        # 003 §6
])
def test_the_manuals_menu_paths_exist(path: str, href: str) -> None:
    menu, item = path.split(" -> ")
    found = menus(nav("/"))
    assert found.get(menu, {}).get(item) == href, found


def test_web_md_lists_the_help_pages_description_files() -> None:
    help_text = (DOCS / "web.md").read_text()
    section = help_text[help_text.index("### Help → Documentation"):]
    section = section[:section.index("\n#")] if "\n#" in section else section
    assert "no GSD" not in section
    for name in descriptions.downloads():  # the ZIP packages and each file, as the page lists them
        assert f"`{name}`" in section, name


def test_fieldbus_md_says_which_identifiers_were_chosen_here() -> None:
    """Every identifier of the shipped GSDML is named in the paragraph on what the manuals do not give."""
    text = (DOCS / "fieldbus.md").read_text()
    para = text[text.index("**Identifiers the manuals do not give.**"):]
    para = " ".join(para[:para.index("\n\n")].split())
    xml = descriptions.read(descriptions.GSDML).decode()
    found = re.findall(r'(?:VendorID|DeviceID|ModuleIdentNumber|SubmoduleIdentNumber)="0x([0-9A-Fa-f]+)"', xml)
    assert found
    for digits in found:  # written as the docs write hex: 02A2h, 00000001h
        assert f"{digits.upper()}h" in para, (digits, para)
    assert "5555h" in para
