"""Help → Documentation: the project's Markdown docs as pages, their images, and the downloads.

``/docs/<name>.md`` renders a doc of the source checkout's ``docs/`` in the page frame (Markdown by
markdown-it-py, which rich already brings; raw HTML in a doc is escaped, not passed through);
``/docs/raw/<name>.md`` is the Markdown itself; ``/docs/img/<name>.png`` the screenshots the docs show.
Only names listed in those folders are served: no path traversal. The downloads are what the
real panel offers and we can honestly provide, generated from the code that implements them: the
command reference (HTML), the fieldbus register map (CSV, manual 003 §4) and the device description
files (GSDML, GSD, their bitmaps and the manual's ZIP packages: :func:`pywsg.fieldbus.descriptions.downloads`).
"""

from __future__ import annotations

import csv
import io
from html import escape
from pathlib import Path

from fastapi import APIRouter, HTTPException, Request
from fastapi.responses import FileResponse, HTMLResponse, PlainTextResponse, Response
from markdown_it import MarkdownIt

from ..fieldbus.image import InputImage, OutputImage
from .context import WebContext
from .fieldbus_view import input_registers, output_registers
from .pages import PROJECT_DOCS, doc_files, render_page
from .reference import command_reference_html

_MD = MarkdownIt("commonmark", {"html": False, "linkify": False}).enable("table")


def doc_images() -> list[str]:
    folder = PROJECT_DOCS / "img"
    return sorted(p.name for p in folder.glob("*.png") if p.is_file()) if folder.is_dir() else []


def _split_title(text: str, name: str) -> tuple[str, str]:
    """(title, the rest): the first ``# `` heading becomes the page's h1, not a second one."""
    lines = text.splitlines(keepends=True)
    for i, line in enumerate(lines):
        if line.startswith("# "):
            return line[2:].strip(), "".join(lines[:i] + lines[i + 1:])
    return name, text


def register_map_csv(model: str = "wsg50") -> str:
    """Both register images with byte offset, Modbus register (``byte[2k] << 8 | byte[2k+1]``), unit."""
    out = io.StringIO()
    w = csv.writer(out)
    w.writerow(["image", "byte_offset", "size_bytes", "modbus_register", "name", "kind", "unit"])
    for image, regs in (("output (PLC to WSG, holding registers)", output_registers(OutputImage(), model)),
                        ("input (WSG to PLC, input registers)", input_registers(InputImage(), model))):
        for r in regs:
            w.writerow([image, r["offset"], r["size"], r["offset"] // 2, r["name"], r["kind"], r.get("unit", "")])
    return out.getvalue()


def _attachment(text: str, media: str, name: str) -> Response:
    return Response(text, media_type=media, headers={"Content-Disposition": f'attachment; filename="{name}"'})


def router(ctx: WebContext) -> APIRouter:
    r = APIRouter(include_in_schema=False)

    def source(name: str) -> Path:
        if name not in doc_files():  # only listed files: no path traversal
            raise HTTPException(404, f"no document {name!r}")
        return PROJECT_DOCS / name

    @r.get("/docs/raw/{name}", response_class=PlainTextResponse)
    async def doc_raw(name: str) -> Response:
        return PlainTextResponse(source(name).read_text(encoding="utf-8"), media_type="text/markdown; charset=utf-8")

    @r.get("/docs/img/{name}")
    async def doc_image(name: str) -> Response:
        if name not in doc_images():
            raise HTTPException(404, f"no image {name!r}")
        return FileResponse(PROJECT_DOCS / "img" / name, media_type="image/png")

    @r.get("/docs/{name}", response_class=HTMLResponse)
    async def doc_page(request: Request, name: str) -> HTMLResponse:
        title, text = _split_title(source(name).read_text(encoding="utf-8"), name)
        body = (f"<p class='small'><a href='/help'>Documentation</a> · <a href='/docs/raw/{escape(name)}' "
                f"download>Markdown source</a></p><article class='doc panel'>{_MD.render(text)}</article>")
        return render_page(ctx, request, "/help", title, "doc.html", "help", doc=body)

    @r.get("/downloads/command-reference.html")
    async def download_reference() -> Response:
        page = ("<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'><title>WSG command reference</title>"
                "</head><body><h1>WSG command reference (pywsg)</h1>"
                f"{command_reference_html()}</body></html>")
        return _attachment(page, "text/html; charset=utf-8", "wsg-command-reference.html")

    @r.get("/downloads/descriptions/{name}")
    async def download_description(name: str) -> Response:
        """A device description file or ZIP package: only names :func:`descriptions.downloads` lists."""
        from ..fieldbus import descriptions

        try:
            data = descriptions.read(name)
        except KeyError:
            raise HTTPException(404, f"no device description file {name!r}") from None
        return Response(data, media_type=descriptions.media_type(name),
                        headers={"Content-Disposition": f'attachment; filename="{name}"'})

    @r.get("/downloads/fieldbus-register-map.csv")
    async def download_register_map() -> Response:
        return _attachment(register_map_csv(), "text/csv; charset=utf-8", "wsg-fieldbus-register-map.csv")

    return r
