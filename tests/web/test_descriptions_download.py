"""Help page: the device description files for download, as the real WSG's web interface offers them
(002 §2.1 GSD, §2.2 GSDML + bitmap)."""

from __future__ import annotations

import httpx

from pywsg.fieldbus import descriptions

from .conftest import LiveSim


def test_help_page_offers_the_description_files(sim: LiveSim, api: httpx.Client) -> None:
    page = api.get("/help").text
    for name in descriptions.names():
        assert f"/downloads/descriptions/{name}" in page
        r = api.get(f"/downloads/descriptions/{name}")
        assert r.status_code == 200 and "attachment" in r.headers["content-disposition"]
        assert r.content == descriptions.read(name)
    assert api.get("/downloads/descriptions/__init__.py").status_code == 404
    assert api.get("/downloads/descriptions/..%2F..%2F__init__.py").status_code == 404
