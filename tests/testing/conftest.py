"""Helpers for the pywsg.testing tests: `wsg` as a subprocess and a `wsg sim` process on free ports."""

from __future__ import annotations

import json
import os
import re
import signal
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from ..ports import free_port
from ..simlog import assert_no_traceback

WSG = [sys.executable, "-c", "from pywsg.cli.main import main; main()"]
ENV = dict(os.environ, PYTHONUNBUFFERED="1", WSG_NO_ENV="1")


def send_then_marker(port: int, blob: bytes) -> None:
    """Send ``blob`` to 127.0.0.1:``port``, then 2,100 zero bytes (they end any frame ``blob`` left
    open) and a Loop request "end"; read the answers until that request's, so everything before it
    has been handled (a proxy or a sim flooded with ``blob``)."""
    from pywsg.protocol import Command, Frame, FrameParser

    with socket.create_connection(("127.0.0.1", port), timeout=30) as s:
        s.sendall(blob + b"\0" * 2100 + Frame(Command.LOOP, b"end").encode())
        parser, done = FrameParser(), False
        while not done:
            chunk = s.recv(1 << 16)
            assert chunk, "closed before the marker's answer"
            done = any(isinstance(e, Frame) and e.command_id == Command.LOOP and e.payload.endswith(b"end")
                       for e in parser.feed(chunk))


def wsg(*args: str, timeout: float = 60, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    """Run ``wsg ARGS`` as a user would; returns the finished process (stdout, stderr, returncode)."""
    return subprocess.run([*WSG, *args], capture_output=True, text=True, timeout=timeout, env=ENV, cwd=cwd)


class SimProc:
    """``wsg sim ARGS`` in a subprocess on free ports; ``.web``, ``.url``, ``.modbus_port``, ``.out`` lines."""

    def __init__(self, *args: str, modbus: bool = False) -> None:
        self.tcp_port = free_port()
        self.modbus_port = free_port() if modbus else 0
        modbus_arg = str(self.modbus_port) if modbus else "off"
        web_port = free_port()  # the CLI's 0 means "off"
        # the default loop as shipped (uvloop when installed); tests/cli's sims run stock asyncio
        argv = [*WSG, "sim", "--tcp-port", str(self.tcp_port), "--udp-port", "0",
                "--serial", "off", "--web-port", str(web_port), "--modbus-port", modbus_arg, *args]
        self.proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=ENV)
        self.out: list[str] = []
        self.url = f"tcp://127.0.0.1:{self.tcp_port}"
        self.web = ""
        deadline = time.monotonic() + 20
        assert self.proc.stdout is not None
        while not self.web:
            line = self.proc.stdout.readline()
            if not line or time.monotonic() > deadline:
                self.stop()
                raise AssertionError("wsg sim did not start:\n" + "".join(self.out) + line)
            self.out.append(line)
            if line.startswith("{"):  # wsg sim --json
                event = json.loads(line)
                if event.get("kind") == "web":
                    self.web = str(event["url"]).rstrip("/")
                continue
            m = re.search(r"web\s+(http://\S+?)/?$", line.strip())
            if m:
                self.web = m.group(1)
        threading.Thread(target=self._drain, daemon=True).start()

    def _drain(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            self.out.append(line)

    def wait_for(self, text: str, timeout: float = 20) -> str:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            for line in list(self.out):
                if text in line:
                    return line
            time.sleep(0.02)
        raise AssertionError(f"{text!r} not in the sim's output:\n" + "".join(self.out))

    def stop(self) -> None:
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGINT)
            try:
                self.proc.wait(10)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()


@pytest.fixture
def sim_proc() -> Iterator[type[SimProc]]:
    """``sim_proc(*args)`` starts a `wsg sim`; all are stopped at teardown."""
    started: list[SimProc] = []

    class _Tracked(SimProc):
        def __init__(self, *args: str, modbus: bool = False) -> None:
            super().__init__(*args, modbus=modbus)
            started.append(self)

    yield _Tracked
    for s in started:
        s.stop()
    for s in started:
        assert_no_traceback(s.out)
