"""Fixtures for the `wsg` command line tests: the real executable, run as a subprocess."""

from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from pywsg import Gripper
from pywsg.protocol import SystemFlag

from ..ports import free_port
from ..simlog import assert_no_traceback

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


class Sim:
    """A `wsg sim` subprocess on free ports (TCP and UDP; UDP replies to the sender's port)."""

    def __init__(self) -> None:
        self.tcp_port = free_port()
        self.udp_port = free_port(socket.SOCK_DGRAM)
        argv = [str(WSG), "sim", "--no-uvloop", "--tcp-port", str(self.tcp_port), "--udp-port", str(self.udp_port),
                "--udp-reply-port", "0", "--serial", "off", "--web-port", "off"]
        self.proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        self.banner: list[str] = []
        deadline = time.monotonic() + 15
        assert self.proc.stdout is not None
        while time.monotonic() < deadline:
            line = self.proc.stdout.readline()
            if not line:
                raise RuntimeError("wsg sim exited:\n" + "".join(self.banner))
            self.banner.append(line)
            if "UDP" in line:
                break
        threading.Thread(target=self._drain, daemon=True).start()
        self.url = f"tcp://127.0.0.1:{self.tcp_port}"
        self.udp_url = f"udp://127.0.0.1:{self.udp_port}?reply_port=0"

    def _drain(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            self.banner.append(line)

    def wsg(self, *args: str, **kw: Any) -> Result:
        return run_wsg(*args, url=self.url, **kw)

    def flags(self) -> SystemFlag:
        """The sim's system state flags (40h), read in this process over TCP (announced disconnect)."""
        with Gripper(self.url, timeout=5.0) as g:
            return g.system_state()

    def ensure_homed(self) -> None:
        """Reference the gripper unless it is: tests that move must not rely on an earlier test's homing."""
        if not self.flags() & SystemFlag.SF_REFERENCED:
            r = self.wsg("home")
            assert r.code == 0, r

    def stop(self) -> None:
        self.proc.send_signal(signal.SIGINT)
        try:
            self.proc.wait(10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
        assert_no_traceback(self.banner)


@pytest.fixture(scope="module")
def _module_sim() -> Iterator[Sim]:
    s = Sim()
    try:
        yield s
    finally:
        s.stop()


@pytest.fixture
def sim(_module_sim: Sim) -> Iterator[Sim]:
    """One `wsg sim` per test module, checked after each test: a test that leaves a FAST STOP (or a
    dead sim) behind fails itself, and the FAST STOP is acknowledged so the next test starts clean."""
    yield _module_sim
    assert _module_sim.proc.poll() is None, "the test left the sim dead:\n" + "".join(_module_sim.banner[-20:])
    if _module_sim.flags() & SystemFlag.SF_FAST_STOP:
        with Gripper(_module_sim.url, timeout=5.0) as g:
            g.acknowledge()
        pytest.fail("the test left the shared sim in FAST STOP (acknowledged now for the next test)")


@pytest.fixture
def homed(sim: Sim) -> Sim:
    """The module's sim, referenced (homed) before the test."""
    sim.ensure_homed()
    return sim
