"""Fixtures for the `wsg` command line tests: the real executable, run as a subprocess."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

WSG = Path(sys.executable).with_name("wsg")


class Result:
    def __init__(self, proc: subprocess.CompletedProcess[str]) -> None:
        self.proc = proc
        self.code = proc.returncode
        self.out = proc.stdout
        self.err = proc.stderr

    def json(self) -> Any:
        return json.loads(self.out)

    def __repr__(self) -> str:
        return f"<wsg exit {self.code}\nstdout:\n{self.out}\nstderr:\n{self.err}>"


def run_wsg(*args: str, url: str | None = None, input: str | None = None, timeout: float = 20.0,
            env: dict[str, str] | None = None) -> Result:
    """Run the installed ``wsg`` with ``args`` (``--url`` first when given)."""
    argv = [str(WSG)]
    if url is not None:
        argv += ["--url", url]
    argv += list(args)
    full_env = {**os.environ, "COLUMNS": "120", "NO_COLOR": "1", **(env or {})}
    full_env.pop("WSG_URL", None)
    proc = subprocess.run(argv, capture_output=True, text=True, input=input, timeout=timeout, env=full_env)
    return Result(proc)


@pytest.fixture(scope="session")
def wsg_exe() -> Path:
    assert WSG.exists(), f"{WSG} missing: pip install -e . in the venv"
    return WSG
