"""`wsg sim` the way a user runs it, on the default loop as shipped (uvloop, installed by ``[web]``) and on
stock asyncio: a browser's WebSocket comes and goes, silent web and Modbus peers reach the idle timeout,
and the sim prints no traceback (issue 33 item 4).

With uvloop, ~60 s (the idle timeout) after a browser's WebSocket closed, the sim printed "Exception in
callback IdleWatch._check ... ValueError: negative file descriptor": uvicorn hands an upgraded connection
to its WebSocket protocol, so the idle watch's connection_lost never ran and its timer asked a closed
socket for TCP_INFO. The rest of the suite ran its sims with ``--no-uvloop`` and never saw it.
"""

from __future__ import annotations

import json
import signal
import socket
import subprocess
import sys
import time

import pytest

from ..simlog import tracebacks
from .test_connection_caps import MODBUS_READ, _closed_within

LOOPS = ["default"]
try:
    import uvloop  # noqa: F401
except ImportError:  # pragma: no cover - [web] brings it; then the default loop is stock asyncio
    pass
else:
    LOOPS.append("--no-uvloop")


@pytest.mark.parametrize("loop", LOOPS)
def test_browser_websockets_and_idle_peers_leave_no_traceback(loop: str) -> None:
    from websockets.sync.client import connect

    argv = [sys.executable, "-c", "from pywsg.cli.main import main; main()", "sim", "--json",
            "--tcp-port", "0", "--udp-port", "off", "--serial", "off", "--modbus-port", "0", "--web-port", "0",
            "--idle-timeout", "1", *([] if loop == "default" else [loop])]
    proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert proc.stdout is not None
        urls: dict[str, str] = {}
        while "web" not in urls or "modbus" not in urls:
            line = proc.stdout.readline()
            assert line, f"wsg sim did not start: {proc.stderr.read() if proc.stderr else ''}"
            event = json.loads(line)
            if event.get("event") == "interface":
                urls[event["kind"]] = event["url"]
        web = urls["web"].rstrip("/").removeprefix("http://")
        host, port = web.rsplit(":", 1)
        mb_host, mb_port = urls["modbus"].split("://", 1)[1].rsplit(":", 1)
        for _ in range(3):  # a browser tab opened and closed: the page's live view is a WebSocket
            with connect(f"ws://{web}/ws", open_timeout=10) as ws:
                ws.recv(timeout=10)
        # opened after the WebSockets closed: once these are closed, the watches of those have fired
        silent_web = socket.create_connection((host, int(port)), timeout=5)
        silent_mb = socket.create_connection((mb_host, int(mb_port)), timeout=5)
        with socket.create_connection((mb_host, int(mb_port)), timeout=5) as master:
            for _ in range(8):  # a master polling every 0.3 s outlives the 1 s idle timeout
                master.sendall(MODBUS_READ)
                assert master.recv(256)[7] == 4
                time.sleep(0.3)
        assert _closed_within(silent_web, 10) and _closed_within(silent_mb, 10)
        silent_web.close()
        silent_mb.close()
    finally:
        proc.send_signal(signal.SIGTERM)
        try:
            _, err = proc.communicate(timeout=20)
        except subprocess.TimeoutExpired:
            proc.kill()
            _, err = proc.communicate()
    assert proc.returncode == 0, err
    assert tracebacks(err) == [], err[-3000:]
