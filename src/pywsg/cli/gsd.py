"""``wsg gsd``: write the device description files and the manuals' ZIP packages (003 §2.1, §3.1)."""

from __future__ import annotations

import json
from pathlib import Path

import click


@click.command("gsd")
@click.option("--out", "out_dir", type=click.Path(file_okay=False, path_type=Path), default=Path("."),
              show_default=True, help="Folder to write the files into (made if missing).")
@click.option("--json", "as_json", is_flag=True, help='One JSON object: {"files": [path, ...]}.')
@click.pass_context
def gsd(ctx: click.Context, out_dir: Path, as_json: bool) -> None:
    """Write the virtual WSG's device description files for an engineering tool.

    The two ZIP packages the manual describes (003 §2.1: WEIS5555.gsd, WSG_D/R/S.bmp, install.txt;
    003 §3.1: the GSDML and its bitmap), then each file on its own. Install them in TIA Portal with
    Options -> Install general station description file (GSD), then find the WSG under Other field
    devices.

    \b
      wsg gsd --out ./gsd
    """
    from ..fieldbus import descriptions

    as_json = as_json or bool((ctx.obj or {}).get("json")) if isinstance(ctx.obj, dict) else as_json
    try:
        written = descriptions.write_all(out_dir)
    except OSError as exc:
        raise click.ClickException(f"{out_dir}: cannot write: {exc.strerror or exc}") from None
    if as_json:
        click.echo(json.dumps({"files": [str(p) for p in written]}))
    else:
        for p in written:
            click.echo(str(p))
