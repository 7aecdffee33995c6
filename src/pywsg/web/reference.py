"""Help → Documentation: the command reference, generated from ``pywsg.protocol.CATALOG``."""

from __future__ import annotations

from html import escape
from typing import Any

from ..protocol import CATALOG, CommandSpec, Field, Status


def _field_json(f: Field) -> dict[str, Any]:
    return {
        "name": f.name, "type": f.type, "unit": f.unit, "description": f.description,
        "choices": [m.name for m in f.enum] if f.enum is not None else [],
        "max_len": f.max_len,
    }


def catalog_json() -> list[dict[str, Any]]:
    """Every command of the catalog as plain data (``GET /api/commands``)."""
    return [
        {
            "id": spec.id, "hex": f"{spec.id:02X}h", "name": spec.name, "title": spec.title,
            "section": spec.section, "description": spec.description, "kind": spec.kind.value,
            "auto_update": spec.auto_update, "motion": spec.motion,
            "request": [_field_json(f) for f in spec.request],
            "reply": [_field_json(f) for f in spec.reply],
            "statuses": [Status(s).name for s in spec.statuses],
        }
        for spec in sorted(CATALOG.values(), key=lambda s: s.id)
    ]


def _fields_table(fields: tuple[Field, ...], empty: str) -> str:
    if not fields:
        return f"<p class='muted'>{escape(empty)}</p>"
    offset = 0
    rows = []
    for f in fields:
        size = f"{f.size}" if f.size else f"0..{f.max_len}"
        where = f"{offset}" if f.size <= 1 else f"{offset}..{offset + f.size - 1}"
        if not f.size:
            where = f"{offset}.."
        offset += f.size
        choices = ""
        if f.enum is not None:
            choices = "<br><small>" + escape(", ".join(f"{int(m.value)} {m.name}" for m in f.enum)) + "</small>"
        rows.append(
            f"<tr><td>{where}</td><td><code>{escape(f.name)}</code></td><td>{escape(f.type)} ({size} B)</td>"
            f"<td>{escape(f.unit)}</td><td>{escape(f.description)}{choices}</td></tr>"
        )
    return ("<table class='grid'><thead><tr><th>Byte</th><th>Name</th><th>Type</th><th>Unit</th>"
            "<th>Description</th></tr></thead><tbody>" + "".join(rows) + "</tbody></table>")


def _spec_html(spec: CommandSpec) -> str:
    flags = [spec.kind.value]
    if spec.motion:
        flags.append("motion command")
    if spec.auto_update:
        flags.append("auto-update capable")
    statuses = ", ".join(f"<code>{escape(Status(s).name)}</code>" for s in spec.statuses)
    return (
        f"<section class='cmd' id='cmd-{spec.id:02X}'>"
        f"<h3>{spec.id:02X}h {escape(spec.title)} <small>({escape(spec.name)}, manual §{escape(spec.section)})"
        f"</small></h3><p>{escape(spec.description)}</p><p class='muted'>{escape('; '.join(flags))}</p>"
        f"<h4>Request parameters</h4>{_fields_table(spec.request, 'none')}"
        f"<h4>Reply parameters (after the 2-byte status code)</h4>{_fields_table(spec.reply, 'none')}"
        f"<p>Status codes: {statuses}</p></section>"
    )


def command_reference_html() -> str:
    """An index and one section per command, in ID order."""
    specs = sorted(CATALOG.values(), key=lambda s: s.id)
    index = "".join(
        f"<li><a href='#cmd-{s.id:02X}'>{s.id:02X}h {escape(s.title)}</a></li>" for s in specs
    )
    return f"<ul class='cmd-index'>{index}</ul>" + "".join(_spec_html(s) for s in specs)
