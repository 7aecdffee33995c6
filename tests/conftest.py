"""Shared test configuration. Subsystems keep their fixtures in their own tests/<pkg>/conftest.py.

Rules every test follows (docs/testing.md "Writing tests for pywsg"): safe under pytest-xdist (port 0, unique
names, no shared files), no absolute wall-time or CPU bounds, generous timeouts that say what they waited for,
and every subprocess killed at teardown. This file enforces the last one for processes started in a test's
body (see ``pytest_runtest_call``) and offers :func:`spawn` / :class:`Processes` for the rest.
"""

from __future__ import annotations

import os
import signal
import subprocess
import threading
import warnings
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import psutil
import pytest
from hypothesis import settings

ARTIFACTS = Path(__file__).resolve().parent.parent / "test-artifacts"
SHARED = Path(os.environ.get("PYWSG_SHARED", Path(__file__).resolve().parents[2] / "shared"))

# Hypothesis: no deadline (a loaded machine is not a bug). "ci" (scripts/test.sh) draws the same examples every
# run and keeps no example database, so a run never depends on what an earlier run found on this machine: a real
# finding is fixed in the code, a test's own mistake in the test, and the input is pinned with @example.
settings.register_profile("ci", deadline=None, derandomize=True, database=None, print_blob=True)
settings.register_profile("dev", deadline=None)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "dev"))

# scripts/test.sh runs the other Pythons' suites as background jobs, and bash starts those with SIGINT ignored;
# an ignored signal stays ignored across exec, so a spawned `wsg` would shrug off the Ctrl-C the signal tests
# send. The suite restores the default for itself and what it spawns.
if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)


def kill_tree(proc: psutil.Process | subprocess.Popen[Any], grace: float = 5.0) -> None:
    """SIGTERM ``proc`` and its children, SIGKILL what is still alive after ``grace`` seconds."""
    try:
        root = psutil.Process(proc.pid)
        tree = [*root.children(recursive=True), root]
    except psutil.NoSuchProcess:
        tree = []
    for p in tree:
        try:
            p.send_signal(signal.SIGTERM)
        except psutil.NoSuchProcess:
            pass
    _gone, alive = psutil.wait_procs(tree, timeout=grace)
    for p in alive:
        try:
            p.kill()
        except psutil.NoSuchProcess:
            pass
    psutil.wait_procs(alive, timeout=grace)
    if isinstance(proc, subprocess.Popen):
        try:
            proc.wait(grace)  # reap it, so no zombie and no ResourceWarning
        except subprocess.TimeoutExpired:
            pass
        for stream in (proc.stdin, proc.stdout, proc.stderr):
            if stream is not None:
                try:
                    stream.close()
                except OSError:
                    pass


class Processes:
    """Subprocesses owned by one fixture scope: :meth:`popen` starts one, :meth:`close` kills them all
    (children too), whether the test passed or failed."""

    def __init__(self) -> None:
        self.procs: list[subprocess.Popen[Any]] = []

    def popen(self, argv: list[str], **kw: Any) -> subprocess.Popen[Any]:
        proc: subprocess.Popen[Any] = subprocess.Popen(argv, **kw)
        self.procs.append(proc)
        return proc

    def close(self) -> None:
        for proc in reversed(self.procs):
            kill_tree(proc)
        self.procs.clear()


@pytest.fixture
def spawn() -> Iterator[Callable[..., subprocess.Popen[Any]]]:
    """``spawn(argv, **popen_kwargs)``: ``subprocess.Popen`` that is killed at this test's teardown."""
    procs = Processes()
    try:
        yield procs.popen
    finally:
        procs.close()


class _TrackedPopen(subprocess.Popen):  # type: ignore[type-arg]
    """``subprocess.Popen`` that notes which processes the main thread (a test's body) started; processes
    that a fixture's worker thread starts in the background (the docs harness runs pages in threads) are
    not a test's to kill."""

    started_by_tests: set[int] = set()  # noqa: RUF012 - one registry for the whole session

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        if threading.current_thread() is threading.main_thread():
            _TrackedPopen.started_by_tests.add(self.pid)


subprocess.Popen = _TrackedPopen  # type: ignore[misc]  # asyncio's subprocesses go through it too

_STARTED_BEFORE = pytest.StashKey[set[int]]()


@pytest.hookimpl(wrapper=True)
def pytest_runtest_call(item: pytest.Item) -> Iterator[None]:
    item.stash[_STARTED_BEFORE] = set(_TrackedPopen.started_by_tests)  # set-up's processes are the fixtures'
    return (yield)


@pytest.hookimpl(wrapper=True)
def pytest_runtest_teardown(item: pytest.Item, nextitem: pytest.Item | None) -> Iterator[None]:
    """Safety net: a process the test's body started that is still running after the test's own teardown
    (a failed assertion before its cleanup, a hung ``wsg``) is killed here, so it cannot hold a session or a
    port for the next test."""
    try:
        return (yield)
    finally:
        before = item.stash.get(_STARTED_BEFORE, None)
        started = _TrackedPopen.started_by_tests - before if before is not None else set()
        _TrackedPopen.started_by_tests -= started
        leaked = []
        for pid in started:
            try:
                p = psutil.Process(pid)
                if p.status() == psutil.STATUS_ZOMBIE or p.ppid() != os.getpid():
                    continue
                cmd = " ".join(p.cmdline())[:120]
            except psutil.NoSuchProcess:
                continue
            leaked.append(f"{pid} {cmd}")
            kill_tree(p)
        if leaked:
            warnings.warn(f"{item.nodeid} left {len(leaked)} process(es) running, killed: {leaked}", stacklevel=1)

# Modules that take longest (a browser, real-time demos, the docs' examples), started first so that no worker
# begins one of them last (scripts/test.sh runs pytest-xdist with --dist loadfile: a module's tests run on one
# worker, in order, sharing its module-scoped fixtures). Add a module here when --durations shows it long.
SLOW_FIRST = (
    "tests/web/test_browser_product.py",
    "tests/test_docs_examples.py",
    "tests/testing/test_scenario.py",
    "tests/web/test_axe.py",
    "tests/web/test_browser.py",
    "tests/testing/test_world_cli.py",
    "tests/testing/test_plugin.py",
    "tests/testing/test_proxy_replay.py",
    "tests/cli/test_commands.py",
    "tests/test_packaging.py",
)


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """The modules of SLOW_FIRST first, in that order; all else as collected (a stable sort)."""
    rank = {path: i for i, path in enumerate(SLOW_FIRST)}
    items.sort(key=lambda item: rank.get(item.nodeid.split("::", 1)[0], len(rank)))
