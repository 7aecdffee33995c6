"""Help → Documentation (issue 15 item 11): the Markdown docs as HTML pages, and honest downloads.

Every docs/*.md renders with working images and relative links; the command reference download
covers the catalog; the register map download is checked against the real Modbus/TCP server
(003 §4.1: coils = output bytes 0..1, holding registers = the output image, discrete inputs =
the input image bit by bit).
"""

from __future__ import annotations

import csv
import io
import re
from pathlib import Path
from typing import Any
from urllib.parse import urljoin, urlsplit

import httpx
import pytest
from pymodbus.client import ModbusTcpClient

from pywsg.fieldbus.image import OutputImage
from pywsg.protocol import CATALOG
from pywsg.web.docs_pages import render_markdown

from .conftest import LiveSim, wait_for

DOCS = Path(__file__).resolve().parents[2] / "docs"


def test_every_doc_renders_with_working_images_and_links(sim: LiveSim, api: httpx.Client) -> None:
    names = sorted(p.name for p in DOCS.glob("*.md"))
    assert "web.md" in names
    images = links = 0
    for name in names:
        r = api.get(f"/docs/{name}")
        assert r.status_code == 200 and r.headers["content-type"].startswith("text/html"), name
        assert "<article class=\"doc\"" in r.text
        base = f"{sim.url}/docs/{name}"
        for src in re.findall(r'<img src="([^"]+)"', r.text):
            img = api.get(urljoin(base, src))
            assert img.status_code == 200 and img.headers["content-type"].startswith("image/"), (name, src)
            images += 1
        for href in re.findall(r'<a href="([^"#:]+)(?:#[^"]*)?"', r.text):
            if href.startswith("/") or href.startswith("?"):
                continue
            target = urlsplit(urljoin(base, href)).path
            assert api.get(target).status_code == 200, (name, href)
            links += 1
    assert images >= 2 and links >= 5


def test_markdown_is_rendered_not_passed_through(api: httpx.Client) -> None:
    page = api.get("/docs/commands.md").text
    assert "<table>" in page and "<h1 id=\"wsg-command-reference\">" in page
    assert "# WSG command reference" not in page
    raw = api.get("/docs/commands.md?format=md")
    assert raw.headers["content-type"].startswith("text/markdown") and raw.text.startswith("# WSG command reference")
    # raw HTML in a document is shown as text, never executed
    assert "<script>" not in render_markdown("<script>alert(1)</script>")


def test_docs_serve_only_files_of_the_docs_folder(api: httpx.Client) -> None:
    for bad in ("/docs/..%2Fpyproject.toml", "/docs/../pyproject.toml", "/docs/img/..%2F..%2Fpyproject.toml",
                "/docs/nothing.md", "/docs/img/"):
        assert api.get(bad).status_code == 404, bad
    assert api.get("/docs/web.md?format=pdf").status_code == 422


def test_command_reference_downloads_cover_the_catalog(api: httpx.Client) -> None:
    r = api.get("/downloads/wsg-commands.csv")
    assert r.status_code == 200 and 'filename="wsg-commands.csv"' in r.headers["content-disposition"]
    rows = list(csv.DictReader(io.StringIO(r.text)))
    assert [int(row["id"]) for row in rows] == sorted(CATALOG)
    grip = next(row for row in rows if row["name"] == "GRIP_PART")
    assert grip["hex"] == "25h" and "width:f32 [mm]" in grip["request"] and "E_CMD_PENDING" in grip["statuses"]
    assert api.get("/downloads/wsg-commands.json").json() == api.get("/api/commands").json()
    assert api.get("/downloads/nothing.csv").status_code == 404


def _map(api: httpx.Client) -> list[dict[str, str]]:
    r = api.get("/downloads/wsg-fieldbus-registers.csv")
    assert r.status_code == 200 and r.headers["content-type"].startswith("text/csv")
    rows = list(csv.DictReader(io.StringIO(r.text)))
    assert [{k: str(v) for k, v in row.items()} for row in api.get("/downloads/wsg-fieldbus-registers.json").json()] \
        == rows
    return rows


def test_register_map_matches_what_the_modbus_server_does(sim: LiveSim, api: httpx.Client) -> None:
    """003 §4.1: each coil row's named flag is the bit the server sets; register rows carry the image."""
    rows = _map(api)
    tables = {t: [r for r in rows if r["table"] == t] for t in
              ("coil", "holding register", "input register", "discrete input")}
    assert [len(v) for v in tables.values()] == [16, 4, 6, 48]
    ctl = sim.modbus.controller
    with ModbusTcpClient("127.0.0.1", port=sim.modbus.port) as mb:
        try:
            # coil 'IF6' (a user flag: no motion) sets exactly the image bit the row names
            row = next(r for r in tables["coil"] if r["name"] == "IF6")
            assert not mb.write_coil(int(row["address"]), True).isError()
            out = sim.call(lambda: ctl.output_bytes)
            assert out[int(row["bytes"])] == 1 << int(row["bit"])
            # holding register 'Width' carries the WIDTH field in 0.01 mm
            row = next(r for r in tables["holding register"] if r["name"] == "Width")
            assert row["unit"] == "0.01 mm"
            assert not mb.write_register(int(row["address"]), 1234).isError()
            assert sim.call(lambda: ctl.output_image).width == 1234
            # discrete input 'SYSSTATE SF_FAST_STOP' reads 1 while FAST STOP is raised
            row = next(r for r in tables["discrete input"] if r["name"] == "SYSSTATE SF_FAST_STOP")
            assert api.post("/api/fast-stop").status_code == 200
            wait_for(lambda: bool(mb.read_discrete_inputs(int(row["address"]), count=1).bits[0]))
            assert api.post("/api/ack").status_code == 200
            wait_for(lambda: not mb.read_discrete_inputs(int(row["address"]), count=1).bits[0])
        finally:
            mb.write_registers(0, OutputImage().registers())


@pytest.mark.browser
def test_help_renders_a_doc_with_its_images_and_offers_downloads(sim: LiveSim, page: Any) -> None:
    page.goto(sim.url + "/help")
    page.click("#doc-links a[href='/docs/web.md']")
    assert page.inner_text("main h1") == "The web interface"
    assert page.locator("article.doc h2").count() >= 3
    # every image loaded (naturalWidth > 0) and fits the column
    imgs = page.locator("article.doc img")
    assert imgs.count() >= 2
    assert page.evaluate("Array.from(document.querySelectorAll('article.doc img'))"
                         ".every(i => i.complete && i.naturalWidth > 0"
                         " && i.clientWidth <= i.parentElement.clientWidth)")
    page.click("#doc-back")
    with page.expect_download() as dl:
        page.click("#download-links a[href='/downloads/wsg-fieldbus-registers.csv']")
    d = dl.value
    assert d.suggested_filename == "wsg-fieldbus-registers.csv"
    assert Path(d.path()).read_text(encoding="utf-8").startswith("table,address,image,bytes,bit,name")
