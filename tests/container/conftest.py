"""The container image under test (scripts/container-env.sh builds it once per run) and podman helpers.

scripts/test.sh starts ``scripts/container-env.sh start`` in the background at its beginning; the first
container test of each module asks ``container-env.sh image``, which waits for that build (a lock file)
or builds the image itself when no run started one. Every container, pod, volume and secret a test makes
carries a name from :func:`unique` and is removed by the test; test.sh removes the image at its end.
"""

from __future__ import annotations

import json
import os
import secrets
import subprocess
import time
import urllib.request
from collections.abc import Iterator
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
ENV_SCRIPT = ROOT / "scripts" / "container-env.sh"
CONF = ROOT / ".venv" / "container" / "containers.conf"
BUILD_TIMEOUT_S = 1800  # a fresh machine makes the Debian base first (minutes)

# every test here may first wait for the image build running beside the suite
pytestmark = [pytest.mark.container, pytest.mark.timeout(BUILD_TIMEOUT_S + 300)]


def podman(*args: str, check: bool = True, timeout: float = 120, **kw: object) -> subprocess.CompletedProcess[str]:
    """``podman ARGS`` with the project's containers.conf (runc, cgroupfs, ulimits: docs/container.md)."""
    env = dict(os.environ, CONTAINERS_CONF=str(CONF))
    r = subprocess.run(["podman", *args], env=env, capture_output=True, text=True, timeout=timeout, **kw)  # type: ignore[call-overload]
    if check and r.returncode != 0:
        raise AssertionError(f"podman {' '.join(args)} -> {r.returncode}\n{r.stdout}\n{r.stderr}")
    return r  # type: ignore[no-any-return]


def unique(what: str) -> str:
    """A name no other test run on this machine uses."""
    return f"pywsg-test-{what}-{os.getpid()}-{secrets.token_hex(3)}"


@pytest.fixture(scope="module")
def image() -> str:
    """The test image's tag, once the build (background or own) is done."""
    r = subprocess.run([str(ENV_SCRIPT), "image"], capture_output=True, text=True, timeout=BUILD_TIMEOUT_S)
    if r.returncode != 0:
        pytest.fail(f"container-env.sh image failed:\n{r.stdout}\n{r.stderr}")
    return r.stdout.strip().splitlines()[-1]


def wait_healthy(web: str, timeout: float = 60.0) -> float:
    """Seconds until ``web/healthz`` answered 200 (a probe that opens no device session)."""
    start = time.monotonic()
    while True:
        try:
            with urllib.request.urlopen(f"{web}/healthz", timeout=2) as reply:
                if reply.status == 200:
                    return time.monotonic() - start
        except OSError:
            pass
        if time.monotonic() - start > timeout:
            raise TimeoutError(f"{web}/healthz did not answer within {timeout:g} s")
        time.sleep(0.05)


def inspect(name: str, what: str = "container") -> dict[str, object]:
    out: list[dict[str, object]] = json.loads(podman(what, "inspect", name).stdout)
    return out[0]


@pytest.fixture
def cleanup() -> Iterator[list[tuple[str, ...]]]:
    """Podman commands to run after the test, last first (``rm -f -v NAME``, ``volume rm NAME``, ...)."""
    todo: list[tuple[str, ...]] = []
    yield todo
    for args in reversed(todo):
        podman(*args, check=False)
