"""Bounded runs of the fuzz targets in fuzz/ (issue 13): the same oracles a long run by hand uses.

Each target's ``test_one_input`` raises on a finding; here it runs on a fixed (derandomized) set of
hypothesis inputs shaped for its surface, plus random bytes. Run longer by hand (fuzz/README.md).
"""

from __future__ import annotations

import importlib
import logging
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from types import ModuleType

import pytest

FUZZ = Path(__file__).resolve().parents[2] / "fuzz"


@pytest.fixture(scope="module")
def fuzz() -> Iterator[None]:
    sys.path.insert(0, str(FUZZ))
    try:
        yield
    finally:
        sys.path.remove(str(FUZZ))


def target(name: str) -> ModuleType:
    return importlib.import_module(name)


def run(name: str, examples: int, raw: bool = True, inputs: str = "inputs") -> None:
    module = target(name)
    harness = target("_harness")
    harness.run_hypothesis(module.test_one_input, getattr(module, inputs), examples, derandomize=True, raw=raw)


@pytest.mark.usefixtures("fuzz")
def test_parser_target() -> None:
    """Frame parser, device and client side (command manual 1.2.1 framing)."""
    run("fuzz_parser", 300)


@pytest.mark.usefixtures("fuzz")
def test_device_target_tcp_stream_and_udp_datagrams() -> None:
    run("fuzz_device", 300)


@pytest.mark.usefixtures("fuzz")
def test_modbus_target_adu_streams(caplog: pytest.LogCaptureFixture) -> None:
    """Modbus/TCP ADUs over a real loopback connection (one maximal ADU per connection: fuzz/README.md F1)."""
    caplog.set_level(logging.ERROR)
    run("fuzz_modbus", 150, raw=False, inputs="suite_inputs")


@pytest.mark.usefixtures("fuzz")
def test_web_target_json_bodies() -> None:
    run("fuzz_web", 150)


@pytest.mark.usefixtures("fuzz")
def test_web_target_bodies_past_the_old_bounds() -> None:
    """Deep nesting and integers of 309 to 20,000 digits to every endpoint (fuzz/README.md F3, F4).

    The same run against the code before those fixes reports HTTP 500 for /api/settings."""
    run("fuzz_web", 200, raw=False, inputs="edge_inputs")


@pytest.mark.usefixtures("fuzz")
def test_device_oracle_catches_a_broken_device(monkeypatch: pytest.MonkeyPatch) -> None:
    """The oracle is not vacuous: a device that answers garbage is a finding."""
    fd = target("fuzz_device")
    from pywsg.device import VirtualGripper
    from pywsg.protocol import Frame, encode_frame

    monkeypatch.setattr(VirtualGripper, "feed", lambda self, s, data: [Frame(0x06, b"")])
    with pytest.raises(AssertionError, match="without a status code"):
        fd.test_one_input(b"\x07" + encode_frame(0x06, b"x"))


@pytest.mark.usefixtures("fuzz")
def test_web_oracle_reports_server_errors(monkeypatch: pytest.MonkeyPatch) -> None:
    """An endpoint that fails with HTTP 500 is a finding."""
    from fastapi import FastAPI
    from starlette.testclient import TestClient

    fw = target("fuzz_web")
    broken = FastAPI()

    @broken.post("/api/move")
    async def move() -> None:
        raise OverflowError("int too large to convert to float")

    client = TestClient(broken, base_url="http://127.0.0.1", raise_server_exceptions=False)
    monkeypatch.setattr(fw, "_client", (client, {}))
    with pytest.raises(AssertionError, match="HTTP 500"):
        fw.test_one_input(bytes([fw.ENDPOINTS.index("/api/move")]) + b'{"width": 1}')


@pytest.mark.parametrize("name", ["fuzz_parser", "fuzz_device", "fuzz_modbus", "fuzz_web"])
def test_targets_run_by_hand(name: str) -> None:
    """``python fuzz/<target>.py --suite --examples N`` works from a shell (fixed inputs: no flaky finding)."""
    out = subprocess.run([sys.executable, str(FUZZ / f"{name}.py"), "--suite", "--examples", "10"],
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr[-2000:]
    assert "10 inputs, no finding" in out.stdout
