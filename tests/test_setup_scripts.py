"""The two set-up commands say what they install before they install it (issue 34 item 9): a first run
is 30-50 s of pip, apt and npm, which looked like a hang when it was silent."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

SCRIPTS = Path(__file__).resolve().parents[1] / "scripts"
INSTALL = re.compile(r"pip install|apt-get\b.*\binstall\b|\bnpm install|\$\{APT\[@\]\}\"? install")


@pytest.mark.parametrize("name", ["demo.sh", "test.sh"])
def test_every_install_step_is_announced_first(name: str) -> None:
    lines = (SCRIPTS / name).read_text().splitlines()
    steps = [n for n, line in enumerate(lines) if INSTALL.search(line) and not line.lstrip().startswith(("#", "echo"))
             and "echo" not in line.split("||")[0]]
    assert steps, f"{name}: no install step found"
    for n in steps:
        before = lines[max(0, n - 4):n]
        assert any(re.search(r"\becho\b.*\b(install|creating|checking)", line, re.IGNORECASE) for line in before), \
            f"{name}:{n + 1} installs without saying so first: {lines[n].strip()}"
