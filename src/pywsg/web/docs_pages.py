"""Help → Documentation: the project's Markdown docs as HTML pages, and the downloads.

``/docs/<name>.md`` renders ``docs/<name>.md`` in the page frame (markdown-it-py: CommonMark plus
tables, raw HTML off), so a document's relative links keep working: ``commands.md`` is the next
page, ``img/x.png`` and ``scenarios/x.toml`` are served from the same folder. ``?format=md`` gives
the Markdown source. Only files found in the docs folder are served (no path traversal).

The docs are read from the source tree (``<repo>/docs``); an installed wheel does not carry them
and the Help page says so. Downloads, generated from what the code uses, never hand-written:

- the command reference (``CATALOG``) as JSON and CSV,
- the fieldbus register map (:mod:`.register_map`) as CSV and JSON.

Device description files (GSD/GSDML, EDS) are not offered: the manuals do not give their content.
"""

from __future__ import annotations

import csv
import io
import json
import mimetypes
import re
from functools import lru_cache
from html import escape
from pathlib import Path
from typing import Any

from fastapi import APIRouter, Request
from fastapi.responses import HTMLResponse, PlainTextResponse, Response
from markdown_it import MarkdownIt
from markdown_it.rules_core import StateCore

from .context import WebContext, error
from .pages import render_page
from .reference import catalog_json, command_reference_html
from .register_map import register_map, register_map_csv

PROJECT_DOCS = Path(__file__).resolve().parents[3] / "docs"  # source checkout only
ASSET_TYPES = {".png", ".jpg", ".jpeg", ".gif", ".svg", ".toml", ".csv", ".json", ".txt"}


def _slug(text: str) -> str:
    """GitHub's heading anchors: lower case, punctuation dropped, spaces to hyphens."""
    return re.sub(r"[^\w\- ]", "", text.strip().lower()).replace(" ", "-")


def _anchors(state: StateCore) -> None:
    seen: dict[str, int] = {}
    tokens = state.tokens
    for i, tok in enumerate(tokens):
        if tok.type == "heading_open" and i + 1 < len(tokens):
            slug = _slug(tokens[i + 1].content)
            n = seen.get(slug, 0)
            seen[slug] = n + 1
            tok.attrSet("id", slug if n == 0 else f"{slug}-{n}")


@lru_cache(maxsize=1)
def _markdown() -> MarkdownIt:
    md = MarkdownIt("commonmark", {"html": False}).enable(["table", "strikethrough"])
    md.core.ruler.push("heading_anchors", _anchors)
    return md


def render_markdown(text: str) -> str:
    """Markdown → HTML (raw HTML in the source is shown as text, not executed)."""
    return str(_markdown().render(text))


def doc_assets(root: Path = PROJECT_DOCS) -> dict[str, Path]:
    """Every servable file under ``root``: Markdown and the asset types, by relative POSIX path."""
    if not root.is_dir():
        return {}
    out: dict[str, Path] = {}
    for p in sorted(root.rglob("*")):
        if p.is_file() and (p.suffix == ".md" or p.suffix.lower() in ASSET_TYPES):
            out[p.relative_to(root).as_posix()] = p
    return out


def doc_title(path: Path) -> str:
    for line in path.read_text(encoding="utf-8").splitlines():
        if line.startswith("# "):
            return line[2:].strip()
    return path.stem


def commands_csv() -> str:
    """One row per command: ID, name, title, manual section, kind, request/reply fields, statuses."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["id", "hex", "name", "title", "section", "kind", "request", "reply", "statuses", "description"])

    def fields(items: list[dict[str, Any]]) -> str:
        return "; ".join(f"{f['name']}:{f['type']}" + (f" [{f['unit']}]" if f["unit"] else "") for f in items)

    for c in catalog_json():
        w.writerow([c["id"], c["hex"], c["name"], c["title"], c["section"], c["kind"], fields(c["request"]),
                    fields(c["reply"]), " ".join(c["statuses"]), c["description"]])
    return buf.getvalue()


# name: (media type, what, body)
DOWNLOADS: dict[str, tuple[str, str]] = {
    "wsg-commands.json": ("application/json", "Command reference (JSON)"),
    "wsg-commands.csv": ("text/csv", "Command reference (CSV)"),
    "wsg-fieldbus-registers.csv": ("text/csv", "Fieldbus register map, Modbus/TCP (CSV)"),
    "wsg-fieldbus-registers.json": ("application/json", "Fieldbus register map, Modbus/TCP (JSON)"),
}


def download_body(name: str) -> str:
    if name == "wsg-commands.json":
        return json.dumps(catalog_json(), indent=1)
    if name == "wsg-commands.csv":
        return commands_csv()
    if name == "wsg-fieldbus-registers.csv":
        return register_map_csv()
    return json.dumps(register_map(), indent=1)


def router(ctx: WebContext) -> APIRouter:
    """``/help``, ``/docs/<path>`` and ``/downloads/<name>``."""
    r = APIRouter(include_in_schema=False)

    @r.get("/help", response_class=HTMLResponse)
    async def help_page(request: Request) -> HTMLResponse:
        files = {k: v for k, v in doc_assets().items() if k.endswith(".md") and "/" not in k}
        docs = "".join(f"<li><a href='/docs/{escape(n)}'>{escape(doc_title(p))}</a> <small class='muted'>"
                       f"{escape(n)}</small></li>" for n, p in files.items()) or \
            "<li class='muted'>The project docs are not installed with this copy: they are the docs/ folder of " \
            "the source repository.</li>"
        downloads = "".join(f"<li><a href='/downloads/{n}' download>{escape(what)}</a> <small class='muted'>"
                            f"{n}</small></li>" for n, (_, what) in DOWNLOADS.items())
        return render_page(ctx, request, "/help", "Documentation", "help.html", "help", docs=docs,
                           downloads=downloads, reference=command_reference_html())

    @r.get("/docs/{path:path}")
    async def doc(request: Request, path: str, format: str = "html") -> Response:
        files = doc_assets()
        if path not in files:  # only listed files: no path traversal
            return error(404, f"no document {path!r}")
        file = files[path]
        if not path.endswith(".md"):
            media = mimetypes.guess_type(file.name)[0] or "text/plain"
            if file.suffix == ".toml":
                media = "text/plain; charset=utf-8"
            return Response(file.read_bytes(), media_type=media)
        text = file.read_text(encoding="utf-8")
        if format == "md":
            return PlainTextResponse(text, media_type="text/markdown; charset=utf-8")
        if format != "html":
            return error(422, "invalid input: format: html or md", {"format": "html or md"})
        return render_page(ctx, request, "/help", doc_title(file), "doc.html", "help", doc=render_markdown(text),
                           source=escape(path))

    @r.get("/downloads/{name}")
    async def download(name: str) -> Response:
        if name not in DOWNLOADS:
            return error(404, f"no download {name!r}")
        media, _ = DOWNLOADS[name]
        return Response(download_body(name), media_type=f"{media}; charset=utf-8",
                        headers={"Content-Disposition": f'attachment; filename="{name}"'})

    return r
