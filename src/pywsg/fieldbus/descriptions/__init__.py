"""Device description files of the virtual WSG (package data): what an engineering tool installs.

- ``GSDML-V2.31-WeissRobotics-WSG-20140401.xml`` and ``GSDML-02A2-0001-WSG.bmp``: PROFINET IO
  (002 §2.2; TIA Portal: Options → Manage general station description files);
- ``WEIS5555.gsd``: PROFIBUS DP (002 §2.1).

:func:`names` lists every file in this folder, so ``wsg gsd --out DIR`` and the web interface's Help
page offer whatever is here without knowing the buses.
"""

from __future__ import annotations

import importlib.resources
from pathlib import Path

_SKIP = ("__init__.py", "__pycache__")


def names() -> list[str]:
    """The description files, sorted by name."""
    folder = importlib.resources.files(__name__)
    return sorted(p.name for p in folder.iterdir() if p.is_file() and p.name not in _SKIP)


def read(name: str) -> bytes:
    """One file's bytes; KeyError for a name :func:`names` does not list (no path traversal)."""
    if name not in names():
        raise KeyError(name)
    return importlib.resources.files(__name__).joinpath(name).read_bytes()


def media_type(name: str) -> str:
    return {".xml": "application/xml", ".bmp": "image/bmp", ".gsd": "text/plain; charset=latin-1"}.get(
        Path(name).suffix.lower(), "application/octet-stream")


def write_all(folder: Path) -> list[Path]:
    """Write every description file into ``folder`` (made if missing); the paths written."""
    folder.mkdir(parents=True, exist_ok=True)
    out = []
    for name in names():
        path = folder / name
        path.write_bytes(read(name))
        out.append(path)
    return out
