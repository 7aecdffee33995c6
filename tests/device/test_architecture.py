"""The shape of device/: small modules, one handler per catalog command (its imports: .importlinter)."""

from __future__ import annotations

from pathlib import Path

from pywsg.device.handlers import HANDLERS
from pywsg.protocol import CATALOG

DEVICE = Path(__file__).resolve().parents[2] / "src" / "pywsg" / "device"


def _module(path: Path) -> str:
    parts = list(path.relative_to(DEVICE).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


# No import cycles and the layers of device/: import-linter contracts in .importlinter ("device",
# "acyclic"), checked by tests/test_architecture.py and scripts/test.sh.


def test_no_module_over_700_lines() -> None:
    sizes = {_module(p) or "__init__": len(p.read_text().splitlines()) for p in DEVICE.rglob("*.py")}
    assert max(sizes.values()) <= 700, sizes


def test_every_catalog_command_has_one_handler() -> None:
    assert set(HANDLERS) == set(CATALOG)
