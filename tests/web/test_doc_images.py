"""The screenshots in docs/img are current: each was taken of this pywsg version.

``shot(..., doc=...)`` in test_browser.py writes docs/img/screenshots.json when run with
PYWSG_UPDATE_DOC_IMAGES=1: the version the page's header showed and the image's SHA-256. This test
needs no browser: it fails when the package version moved on (the images show an old "pywsg x.y.z"),
when an image was replaced by hand, or when an image has no entry.
"""

from __future__ import annotations

import hashlib
import json

import pywsg

from .conftest import DOC_IMAGES, DOC_IMAGES_MANIFEST

REGENERATE = ("PYWSG_UPDATE_DOC_IMAGES=1 pytest -p no:cacheprovider tests/web/test_browser.py "
              "tests/web/test_browser_product.py tests/web/commander/test_commander_axe.py")


def test_every_docs_screenshot_shows_the_current_version() -> None:
    manifest = json.loads(DOC_IMAGES_MANIFEST.read_text())
    images = sorted(p.name for p in DOC_IMAGES.glob("*.png"))
    assert images, "docs/img has no screenshots"
    assert sorted(manifest) == images, f"docs/img/screenshots.json does not list exactly the images; run {REGENERATE}"
    for name in images:
        entry = manifest[name]
        assert entry["pywsg"] == pywsg.__version__, \
            f"docs/img/{name} shows pywsg {entry['pywsg']}, the package is {pywsg.__version__}: run {REGENERATE}"
        digest = hashlib.sha256((DOC_IMAGES / name).read_bytes()).hexdigest()
        assert entry["sha256"] == digest, f"docs/img/{name} was not written by the screenshot tests: run {REGENERATE}"
