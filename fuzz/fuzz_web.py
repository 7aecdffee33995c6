"""Fuzz the web interface's JSON bodies: the POST endpoints of /api and /api/sim that take a body.

    .venv/bin/python fuzz/fuzz_web.py -max_total_time=60            # atheris
    .venv/bin/python fuzz/fuzz_web.py --hypothesis --examples 2000  # without atheris

The app (:func:`pywsg.web.app.create_app`, the same ASGI app ``wsg sim`` serves) runs in-process
through Starlette's TestClient, with a session and its CSRF token. Byte 0 of an input picks the
endpoint, the rest is the body. A finding is any answer >= 500 (an unhandled error), an error answer
that is not the documented JSON (``detail`` and ``errors``), or an app that afterwards no longer
answers ``GET /api/state``.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

from hypothesis import strategies as st

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _harness import instrumented, main

with instrumented(__name__):
    from starlette.testclient import TestClient

    from pywsg.device import ManualClock, VirtualGripper
    from pywsg.web.app import create_app

ENDPOINTS = ("/api/move", "/api/grip", "/api/release", "/api/home", "/api/settings", "/api/stop",
             "/api/sim/part", "/api/sim/block", "/api/sim/heat", "/api/sim/fault",
             "/api/tag", "/api/soft-limits", "/api/overdrive", "/api/jog")
FIELDS = ("width", "speed", "force", "relative", "stop_on_block", "direction", "stiffness", "delta_c", "kind",
          "on", "crc_check", "fast_stop_on_disconnect", "homing_direction", "clamping_travel", "model",
          "default_acceleration", "default_force_limit", "serial_number", "finger1", "finger2", "script",
          "auto_homing", "tag", "minus", "plus")

_client: tuple[TestClient, dict[str, str]] | None = None


def _app() -> tuple[TestClient, dict[str, str]]:
    global _client
    if _client is None:
        app = create_app(VirtualGripper("wsg50", clock=ManualClock()), loopback=True)
        client = TestClient(app, base_url="http://127.0.0.1", raise_server_exceptions=False)
        token = client.get("/api/csrf").json()["token"]
        _client = (client, {"X-CSRF-Token": token, "Content-Type": "application/json",
                            "Origin": "http://127.0.0.1"})
    return _client


def test_one_input(data: bytes) -> None:
    if not data:
        return
    client, headers = _app()
    path = ENDPOINTS[data[0] % len(ENDPOINTS)]
    r = client.post(path, content=data[1:], headers=headers)
    if r.status_code >= 500:
        raise AssertionError(f"POST {path} {data[1:200]!r}: HTTP {r.status_code} {r.text[:200]}")
    if r.status_code >= 400:
        body: Any = r.json()
        if not isinstance(body, dict) or "detail" not in body:
            raise AssertionError(f"POST {path}: HTTP {r.status_code} without a detail: {r.text[:200]}")
    state = client.get("/api/state")
    if state.status_code != 200:
        raise AssertionError(f"after POST {path} {data[1:200]!r}: GET /api/state is {state.status_code}")


# JSON bodies: objects with the endpoints' field names and values of every JSON type, including
# integers far beyond the float range (fuzz/README.md F4) and beyond Python's 4,300-digit int limit
_huge = st.integers(309, 4300).flatmap(lambda n: st.sampled_from([int("9" * n), -(10 ** (n - 1))]))
_scalar = st.one_of(st.none(), st.booleans(), st.integers(), st.integers(-(10**400), 10**400), _huge, st.floats(),
                    st.text(max_size=12), st.sampled_from(["wsg50", "fmf", "power", "current", "default", "ack"]))
_json = st.recursive(_scalar, lambda inner: st.one_of(st.lists(inner, max_size=4),
                                                     st.dictionaries(st.text(max_size=8), inner, max_size=4)),
                     max_leaves=12)
_doc = st.one_of(
    st.dictionaries(st.sampled_from(FIELDS), _json, max_size=6),
    _json,
).map(lambda v: json.dumps(v).encode())


def _nest(depth: int, arrays: bool, field: str | None) -> bytes:
    """``depth`` nested arrays or objects (F3), bare or as the value of ``field``; 5,000 levels is 10 KB."""
    inner = b"[" * depth + b"]" * depth if arrays else b'{"a":' * depth + b"1" + b"}" * depth
    return inner if field is None else b'{"' + field.encode() + b'": ' + inner + b"}"


_deep = st.builds(_nest, st.sampled_from([1000, 2500, 5000]) | st.integers(50, 6000), st.booleans(),
                  st.none() | st.sampled_from(FIELDS))
# digits as text (309 and more: past the float range; past 4,300 json.dumps refuses a Python int)
_digits = st.builds(lambda field, n, sign: f'{{"{field}": {sign}{"9" * n}}}'.encode(),
                    st.sampled_from(FIELDS), st.sampled_from([400, 4300, 5000]) | st.integers(309, 20000),
                    st.sampled_from(["", "-"]))
_body = st.one_of(_doc, _deep, _digits)
inputs = st.builds(lambda i, body: bytes([i]) + body, st.integers(0, 255), _body)
# only the inputs beyond the old bounds (findings F3, F4), to every endpoint: the test suite's regression run
edge_inputs = st.builds(lambda i, body: bytes([i]) + body, st.integers(0, len(ENDPOINTS) - 1),
                        st.one_of(_deep, _digits))


if __name__ == "__main__":
    main(test_one_input, inputs)
