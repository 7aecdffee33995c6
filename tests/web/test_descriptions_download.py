"""Help page: the device description files and the manual's ZIP packages for download, as the real WSG's
web interface offers them (003 §2.1 PROFIBUS package, §3.1 PROFINET package)."""

from __future__ import annotations

from urllib.parse import quote

import httpx

from pywsg.fieldbus import descriptions

from .conftest import LiveSim


def test_help_page_offers_the_description_files_and_packages(sim: LiveSim, api: httpx.Client) -> None:
    page = api.get("/help").text
    assert descriptions.downloads()[:2] == ["WEIS5555.zip", "GSDML-V2.31-Weiss Robotics-WSG-20140401.zip"]
    for name in descriptions.downloads():
        assert f"/downloads/descriptions/{quote(name)}" in page
        r = api.get(f"/downloads/descriptions/{quote(name)}")
        assert r.status_code == 200 and "attachment" in r.headers["content-disposition"]
        assert r.content == descriptions.read(name)
    assert api.get("/downloads/descriptions/WEIS5555.zip").headers["content-type"] == "application/zip"
    assert "PROFIBUS package, 003 §2.1" in page
    assert api.get("/downloads/descriptions/__init__.py").status_code == 404
    assert api.get("/downloads/descriptions/bitmaps.py").status_code == 404
    assert api.get("/downloads/descriptions/..%2F..%2F__init__.py").status_code == 404
