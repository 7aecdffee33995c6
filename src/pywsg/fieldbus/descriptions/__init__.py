"""Device description files of the virtual WSG (package data): what an engineering tool installs.

- ``GSDML-V2.31-Weiss Robotics-WSG-20140401.gsdml`` and ``GSDML-02A2-0001-WSG.bmp``: PROFINET IO
  (003 §3.1; TIA Portal: Options → Install general station description file);
- ``WEIS5555.gsd`` with ``WSG_D.bmp``, ``WSG_R.bmp``, ``WSG_S.bmp`` (:mod:`.bitmaps`) and ``install.txt``:
  PROFIBUS DP (003 §2.1).

Both manuals hand these out as ZIP packages (003 §2.1, §3.1): :data:`PACKAGES` names them and
:func:`package` builds them. :func:`names` lists every file in this folder, so ``wsg gsd --out DIR`` and
the web interface's Help page offer whatever is here without knowing the buses.
"""

from __future__ import annotations

import importlib.resources
import io
import zipfile
from pathlib import Path

GSDML = "GSDML-V2.31-Weiss Robotics-WSG-20140401.gsdml"
GSD_ZIP, GSDML_ZIP = "WEIS5555.zip", "GSDML-V2.31-Weiss Robotics-WSG-20140401.zip"
#: ZIP package → its files, in the order the manual lists them (003 §2.1 PROFIBUS, §3.1 PROFINET).
PACKAGES: dict[str, tuple[str, ...]] = {
    GSD_ZIP: ("WEIS5555.gsd", "WSG_D.bmp", "WSG_R.bmp", "WSG_S.bmp", "install.txt"),
    GSDML_ZIP: (GSDML, "GSDML-02A2-0001-WSG.bmp"),
}
#: What each package is, for a download list.
NOTES = {GSD_ZIP: " (PROFIBUS package, 003 §2.1: GSD, three bitmaps, install.txt)",
         GSDML_ZIP: " (PROFINET package, 003 §3.1: GSDML and its bitmap)"}
#: Every member gets this time stamp, so a package's bytes depend only on its files (the GSDML's date).
_ZIP_TIME = (2014, 4, 1, 0, 0, 0)


def names() -> list[str]:
    """The description files, sorted by name (not the Python modules beside them)."""
    folder = importlib.resources.files(__name__)
    return sorted(p.name for p in folder.iterdir() if p.is_file() and not p.name.endswith((".py", ".pyc")))


def downloads() -> list[str]:
    """What ``wsg gsd`` writes and the Help page offers: the ZIP packages, then the single files."""
    return [*PACKAGES, *names()]


def package(name: str) -> bytes:
    """One ZIP package of :data:`PACKAGES` (KeyError for another name)."""
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as z:
        for member in PACKAGES[name]:
            info = zipfile.ZipInfo(member, _ZIP_TIME)
            info.compress_type = zipfile.ZIP_DEFLATED
            info.external_attr = 0o644 << 16
            z.writestr(info, read(member))
    return buf.getvalue()


def read(name: str) -> bytes:
    """One file's or package's bytes; KeyError for a name :func:`downloads` does not list (no path traversal)."""
    if name in PACKAGES:
        return package(name)
    if name not in names():
        raise KeyError(name)
    return importlib.resources.files(__name__).joinpath(name).read_bytes()


def media_type(name: str) -> str:
    return {".gsdml": "application/xml", ".xml": "application/xml", ".bmp": "image/bmp",
            ".gsd": "text/plain; charset=latin-1", ".txt": "text/plain; charset=us-ascii",
            ".zip": "application/zip"}.get(Path(name).suffix.lower(), "application/octet-stream")


def write_all(folder: Path) -> list[Path]:
    """Write every package and description file into ``folder`` (made if missing); the paths written."""
    folder.mkdir(parents=True, exist_ok=True)
    out = []
    for name in downloads():
        path = folder / name
        path.write_bytes(read(name))
        out.append(path)
    return out
