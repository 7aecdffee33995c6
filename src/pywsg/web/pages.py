"""The HTML pages: the menu, the page frame (``base.html``) and one route per page.

A page is a template in ``templates/`` plus a script in ``static/``; the live values arrive over
the WebSocket (``live.py``) and commands go to the JSON API (``api.py``), so the routes here only
render. To add a page: a row in ``PAGES`` (and in ``MENU`` for the menu), a template, a script.
"""

from __future__ import annotations

from collections.abc import Awaitable, Callable
from html import escape
from pathlib import Path
from string import Template
from urllib.parse import quote

from fastapi import APIRouter, Request
from fastapi.responses import HTMLResponse

from .. import __version__
from .context import WebContext
from .reference import command_reference_html
from .security import CSRF_FIELD, WebSession

HERE = Path(__file__).resolve().parent
TEMPLATES = HERE / "templates"
PROJECT_DOCS = HERE.parents[2] / "docs"  # source checkout only; the Help page says when missing

# The menu bar of manual 003 §6, figure 1: "Settings | Diagnostics | Scripting | Motion | Help", named as
# the manuals' menu paths name it, so each path they give exists: "Settings -> Command Interface" (000
# §1.4.1, §1.4.2), "Settings -> Motion Configuration" (003 §4), "Diagnosis -> Fieldbus Monitor" (003 §6);
# Motion keeps the figure's Motion Configuration too (docs/fidelity.md "Menu names"). After the Control
# Panel (the figure's title) and before pywsg's own Simulation page.
MENU: list[tuple[str, list[tuple[str, str]]]] = [
    ("Control Panel", [("/", "Control Panel")]),
    ("Settings", [("/settings/interface", "Command Interface"), ("/settings/motion", "Motion Configuration")]),
    ("Diagnosis", [("/diagnosis/log", "System Log"), ("/diagnosis/fieldbus", "Fieldbus Monitor")]),
    ("Scripting", [("/scripting", "Scripting")]),
    ("Motion", [("/settings/motion", "Motion Configuration")]),
    ("Simulation", [("/simulation", "Simulation")]),
    ("Help", [("/help", "Documentation")]),
]

# path: (title, template, script)
PAGES: dict[str, tuple[str, str, str]] = {
    "/": ("Control Panel", "control.html", "control"),
    "/settings/interface": ("Command Interface", "settings.html", "settings"),
    "/settings/motion": ("Motion Configuration", "settings.html", "settings"),
    "/diagnosis/log": ("System Log", "log.html", "log"),
    "/diagnosis/fieldbus": ("Fieldbus Monitor", "fieldbus.html", "fieldbus"),
    "/scripting": ("Scripting", "scripting.html", "scripting"),
    "/simulation": ("Simulation", "simulation.html", "simulation"),
}


def template(name: str) -> Template:
    return Template((TEMPLATES / name).read_text(encoding="utf-8"))


def nav(current: str) -> str:
    """The menu bar; a menu with several pages is a WAI-ARIA disclosure (a button that opens a list)."""
    parts = []
    for title, items in MENU:
        active = any(href == current for href, _ in items)
        if len(items) == 1:
            href, _ = items[0]
            here = " aria-current='page'" if active else ""
            parts.append(f"<li class='{'active' if active else ''}'><a href='{href}'{here}>{escape(title)}</a></li>")
            continue
        links = "".join(
            f"<li><a href='{href}' class='{'active' if href == current else ''}'"
            f"{' aria-current=page' if href == current else ''}>{escape(label)}</a></li>"
            for href, label in items
        )
        menu_id = "menu-" + title.lower()
        parts.append(f"<li class='menu {'active' if active else ''}'>"
                     f"<button type='button' aria-expanded='false' aria-controls='{menu_id}'>{escape(title)}</button>"
                     f"<ul id='{menu_id}' hidden>{links}</ul></li>")
    return "<ul class='nav'>" + "".join(parts) + "</ul>"


def render_page(ctx: WebContext, request: Request, path: str, title: str, body_template: str, script: str,
                **extra: str) -> HTMLResponse:
    s: WebSession = request.state.websession
    body = template(body_template).safe_substitute(**extra)
    if ctx.auth.login_possible:
        user = ("<form method='post' action='/logout' class='inline'>"
                f"<input type='hidden' name='{CSRF_FIELD}' value='{escape(s.csrf)}'>"
                "<button type='submit' id='logout'>Log out</button></form>") if s.authenticated else \
            f"<a href='/login?next={quote(path)}' id='login-link'>Log in</a>"
    else:
        user = "<span class='muted'>local access</span>"
    page = template("base.html").safe_substitute(
        title=escape(title), model=escape(ctx.model_name()), nav=nav(path), body=body, csrf=escape(s.csrf),
        user=user, script=escape(script), version=escape(__version__),
        can_write="true" if ctx.auth.may_write(s) else "false",
    )
    return HTMLResponse(page, headers={"Cache-Control": "no-store"})


def not_found_page(ctx: WebContext, request: Request, what: str) -> HTMLResponse:
    """The 404 page in the interface's frame (the menu still works from it)."""
    body = (f"<p class='banner bad' role='alert'>{escape(what)}</p>"
            "<p>The page may have moved; the menu above leads to every page of the interface. "
            "<a href='/'>Back to the Control Panel</a>.</p>")
    s: WebSession = request.state.websession
    page = template("base.html").safe_substitute(
        title="Page not found", model=escape(ctx.model_name()), nav=nav(""), body=body, csrf=escape(s.csrf),
        user="", script="notfound", version=escape(__version__),
        can_write="true" if ctx.auth.may_write(s) else "false")
    return HTMLResponse(page, status_code=404, headers={"Cache-Control": "no-store"})


def doc_files() -> list[str]:
    if not PROJECT_DOCS.is_dir():
        return []
    return sorted(p.name for p in PROJECT_DOCS.glob("*.md") if p.is_file())


def router(ctx: WebContext) -> APIRouter:
    """The pages of ``PAGES`` and Help (the docs themselves: ``help_docs``)."""
    r = APIRouter(include_in_schema=False)

    def make(path: str, title: str, tpl: str, script: str) -> Callable[[Request], Awaitable[HTMLResponse]]:
        group = "interface" if path.endswith("interface") else "motion"
        panels = template(f"{group}_panels.html").template if tpl == "settings.html" else ""

        async def page(request: Request) -> HTMLResponse:
            return render_page(ctx, request, path, title, tpl, script, group=group, heading=escape(title),
                               panels=panels)

        return page

    for path, (title, tpl, script) in PAGES.items():
        r.add_api_route(path, make(path, title, tpl, script), methods=["GET"], response_class=HTMLResponse)

    @r.get("/help", response_class=HTMLResponse)
    async def help_page(request: Request) -> HTMLResponse:
        files = doc_files()
        docs = "".join(f"<li><a href='/docs/{escape(n)}'>{escape(n)}</a></li>" for n in files) or \
            "<li class='muted'>project docs are not installed with this copy (see the repository's docs/)</li>"
        from ..fieldbus import descriptions

        gsd = "".join(f"<li><a href='/downloads/descriptions/{quote(n)}' download>{escape(n)}</a>"
                      f"{escape(descriptions.NOTES.get(n, ''))}</li>" for n in descriptions.downloads())
        return render_page(ctx, request, "/help", "Documentation", "help.html", "help", docs=docs,
                           reference=command_reference_html(), descriptions=gsd)

    return r
