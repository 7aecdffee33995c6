"""The command reference as Markdown, generated from the catalog.

``python -m pywsg.protocol.reference > docs/commands.md`` — a test checks the file is current.
"""

from __future__ import annotations

from .catalog import CATALOG, Field, Kind


def _fields(fields: tuple[Field, ...]) -> str:
    if not fields:
        return "none"
    rows = []
    offset = 0
    for f in fields:
        span = f"{offset}..{offset + f.size - 1}" if f.size > 1 else (f"{offset}" if f.size else f"{offset}..n")
        rows.append(f"`{f.name}` ({f.type}{', ' + f.unit if f.unit else ''}, bytes {span}): {f.description}")
        offset += f.size
    return "<br>".join(rows)


def markdown() -> str:
    """Every command: ID, name, section of the manual, parameters, reply, kind and status codes."""
    lines = [
        "# WSG command reference",
        "",
        "Generated from `pywsg.protocol.catalog` (`python -m pywsg.protocol.reference`). Sections refer to the",
        "WSG Command Set Reference Manual. Replies start with the 2-byte status code; parameters follow only",
        "with E_SUCCESS.",
        "",
        "| ID | command | § | parameters | reply | kind | status codes |",
        "|---|---|---|---|---|---|---|",
    ]
    for spec in CATALOG.values():
        kind = spec.kind.value
        if spec.auto_update:
            kind += ", auto-update"
        if spec.motion:
            kind += ", motion"
        if spec.kind is Kind.IMMEDIATE and not spec.auto_update and not spec.motion:
            kind = "immediate"
        statuses = ", ".join(s.name for s in dict.fromkeys(spec.statuses))
        lines.append(
            f"| {spec.id:02X}h | **{spec.name}**<br>{spec.title}: {spec.description} | {spec.section} | "
            f"{_fields(spec.request)} | {_fields(spec.reply)} | {kind} | {statuses} |"
        )
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    print(markdown(), end="")
