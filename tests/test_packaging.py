"""The sdist and wheel a packager builds: licence, metadata, tests in the sdist, README fit for the index.

Builds with ``python -m build --no-isolation`` (offline; setuptools and build come with the test extra)
from a copy of the checkout, so nothing is written into the working tree; the wheel is built from the
sdist, which proves the sdist is complete.
"""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
import tarfile
import zipfile
from email.parser import Parser
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SKIP = shutil.ignore_patterns(".venv", ".git", "build", "dist", "*.egg-info", "__pycache__", ".*_cache",
                              ".hypothesis", "*.pyc")


@pytest.fixture(scope="module")
def built(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    tmp = tmp_path_factory.mktemp("pkg")
    src = tmp / "src-copy"
    shutil.copytree(ROOT, src, ignore=SKIP)
    out = tmp / "dist"
    r = subprocess.run([sys.executable, "-m", "build", "--no-isolation", "--outdir", str(out), str(src)],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    assert "License classifiers are deprecated" not in r.stdout + r.stderr
    assert "`project.license` as a TOML table is deprecated" not in r.stdout + r.stderr
    (sdist,) = out.glob("pywsg-*.tar.gz")
    (wheel,) = out.glob("pywsg-*.whl")
    return sdist, wheel


def test_sdist_carries_the_tests_docs_scripts_and_licence(built: tuple[Path, Path]) -> None:
    sdist, _ = built
    with tarfile.open(sdist) as tar:
        names = {n.split("/", 1)[1] for n in tar.getnames() if "/" in n}
    for needed in ("LICENSE", "README.md", "CHANGELOG.md", "pyproject.toml", "MANIFEST.in",
                   "tests/conftest.py", "tests/cli/conftest.py", "tests/test_docs_examples.py",
                   "tests/protocol/__init__.py", "docs/cli.md", "scripts/demo.sh", "scripts/test.sh",
                   "src/pywsg/cli/main.py", "src/pywsg/py.typed"):
        assert needed in names, f"{needed} missing from the sdist"
    assert not any("__pycache__" in n or n.endswith(".pyc") for n in names)


def test_wheel_metadata_licence_and_entry_point(built: tuple[Path, Path]) -> None:
    _, wheel = built
    with zipfile.ZipFile(wheel) as z:
        names = z.namelist()
        meta_name = next(n for n in names if n.endswith(".dist-info/METADATA"))
        meta = Parser().parsestr(z.read(meta_name).decode())
        entry = z.read(next(n for n in names if n.endswith(".dist-info/entry_points.txt"))).decode()
        assert any(n.endswith(".dist-info/licenses/LICENSE") for n in names)
        assert "MIT License" in z.read(next(n for n in names if n.endswith("licenses/LICENSE"))).decode()
    assert meta["License-Expression"] == "MIT"
    assert meta["Name"] == "pywsg" and meta["Requires-Python"] == ">=3.10"
    assert "wsg = pywsg.cli.main:main" in entry
    assert "pywsg/web/static/app.js" in names or any(n.startswith("pywsg/web/static/") for n in names)
    assert not any(n.startswith("tests/") for n in names)  # tests ship in the sdist, not the wheel
    # the long description is the README, and it holds up on an index page
    body = meta.get_payload()
    assert isinstance(body, str) and "## Quick start" in body


def test_twine_check_passes(built: tuple[Path, Path]) -> None:
    """What the package index checks on upload (the long description renders, metadata complete):
    the release steps of docs/testing.md are then one command away."""
    r = subprocess.run([sys.executable, "-m", "twine", "check", "--strict", *map(str, built)],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stdout + r.stderr
    assert r.stdout.count("PASSED") == 2, r.stdout


def test_project_urls_are_absent_or_real() -> None:
    text = (ROOT / "pyproject.toml").read_text(encoding="utf-8")
    for url in re.findall(r"https?://[^\s\"']+", text):
        host = url.split("/")[2]
        assert not any(bad in host for bad in ("example", "pypi.org", "localhost", "TODO", "your")), url


def _images(text: str) -> list[str]:
    return re.findall(r"!\[[^\]]*\]\(([^)]+)\)", text) + re.findall(r"<img[^>]+src=\"([^\"]+)\"", text)


def test_the_index_page_has_no_image_that_would_vanish_and_the_readmes_exist() -> None:
    """The package index shows the long description on its own: relative images vanish there, so it is
    docs/package-description.md (no images); README.md's screenshots are files of the repository."""
    meta = (ROOT / "pyproject.toml").read_text(encoding="utf-8")
    page = re.search(r'^readme = "([^"]+)"', meta, re.M)
    assert page is not None and page.group(1) == "docs/package-description.md"
    assert all(re.match(r"https?://", src) for src in _images((ROOT / page.group(1)).read_text(encoding="utf-8")))
    readme = _images((ROOT / "README.md").read_text(encoding="utf-8"))
    assert readme and all((ROOT / src).is_file() for src in readme), readme


def test_code_and_tests_cite_the_manuals_not_notes_outside_the_repository() -> None:
    """Comments cite the manuals (000..003 §...) or docs/fidelity.md; the notes they were written from
    are not shipped, so a reader could not follow such a citation."""
    outside = ("SPEC" + "-NOTES", "../" + "shared")   # spelled in parts so this file does not find itself
    guards = {ROOT / "tests" / "test_docs_examples.py"}   # the docs' own check names them in its rules
    found = [f"{p.relative_to(ROOT)}:{n}" for folder in ("src", "tests", "benchmarks")
             for p in sorted((ROOT / folder).rglob("*.py")) if p not in guards
             for n, line in enumerate(p.read_text(encoding="utf-8").splitlines(), 1)
             if any(word in line for word in outside)]
    assert not found, "cite the manual section or docs/fidelity.md instead:\n" + "\n".join(found)
