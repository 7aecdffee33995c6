"""The package's shape: the import contracts (layers, no front end below, no cycles) hold, and no
module grows past 700 lines. The contracts live in .importlinter; docs/architecture.md draws them."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SRC = ROOT / "src" / "pywsg"
MAX_LINES = 700


def test_import_contracts_hold() -> None:
    lint = Path(sys.executable).parent / "lint-imports"
    r = subprocess.run([str(lint), "--no-cache"], cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stdout + r.stderr
    assert "0 broken" in r.stdout and " kept" in r.stdout, r.stdout


def test_no_module_over_700_lines() -> None:
    sizes = {str(p.relative_to(SRC)): len(p.read_text(encoding="utf-8").splitlines()) for p in SRC.rglob("*.py")}
    over = {name: n for name, n in sizes.items() if n > MAX_LINES}
    assert not over, f"modules over {MAX_LINES} lines (split them by what they do): {over}"


def test_the_blocking_commands_are_generated_into_a_folder_of_their_own() -> None:
    """Edit here, generated there: the asyncio source and the generated blocking methods."""
    assert (SRC / "client" / "_async" / "commands.py").is_file()
    generated = (SRC / "client" / "_sync" / "generated_commands.py").read_text(encoding="utf-8")
    assert generated.startswith('"""GENERATED from ``pywsg/client/_async/commands.py``')
