"""The docs a newcomer follows: no references a reader cannot look up, and claims that are true."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]


def test_docs_cite_no_issue_numbers() -> None:
    """"(issue 11)" means nothing to a reader of the repository: say what the work was instead.
    (Another project's issue, "owner/repo issue 326", can be looked up and is fine.)"""
    found = [f"{p.name}:{n}" for p in PAGES for n, line in enumerate(p.read_text().splitlines(), 1)
             for m in re.finditer(r"(\S*)\s+issues? \d+\b", " " + line, re.IGNORECASE) if "/" not in m.group(1)]
    assert not found, found


def test_readme_fixture_example_shows_the_manual_clock() -> None:
    text = (ROOT / "README.md").read_text()
    fixture = text[text.index("`wsg_sim` fixture"):]
    assert '@pytest.mark.wsg_sim(clock="manual")' in fixture and "world.advance(" in fixture


def test_unmarked_async_test_fails_as_testing_md_says(tmp_path: Path) -> None:
    """docs/testing.md: pytest fails an unmarked `async def` test, with pytest-asyncio's strict mode too."""
    assert "Since pytest 8.4 it fails them" in (ROOT / "docs" / "testing.md").read_text()
    (tmp_path / "test_unmarked.py").write_text("async def test_unmarked():\n    assert True\n")
    for plugins in (["-p", "no:asyncio"], []):
        r = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-p", "no:anyio",
                            *plugins, "test_unmarked.py"], cwd=tmp_path, capture_output=True, text=True,
                           timeout=120)
        assert r.returncode == 1, r.stdout
        assert "1 failed" in r.stdout and "not natively supported" in r.stdout, r.stdout


def test_web_and_sim_docs_have_no_paragraphs_in_table_cells() -> None:
    for name in ("web.md", "sim.md"):
        for n, line in enumerate((ROOT / "docs" / name).read_text().splitlines(), 1):
            if line.startswith("|"):
                cells = re.split(r"(?<!\\)\|", line.strip())[1:-1]
                assert all(len(c) <= 300 for c in cells), f"{name}:{n}: a paragraph in a table cell"
