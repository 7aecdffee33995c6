"""Shared test configuration. Subsystems keep their fixtures in their own tests/<pkg>/conftest.py."""

from __future__ import annotations

import os
from pathlib import Path

ARTIFACTS = Path(__file__).resolve().parent.parent / "test-artifacts"
SHARED = Path(os.environ.get("PYWSG_SHARED", Path(__file__).resolve().parents[2] / "shared"))
