"""Fuzz the web interface's JSON bodies: every POST endpoint of /api and /api/sim.

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
             "/api/sim/part", "/api/sim/block", "/api/sim/heat", "/api/sim/fault")
FIELDS = ("width", "speed", "force", "relative", "stop_on_block", "direction", "stiffness", "delta_c", "kind",
          "on", "crc_check", "fast_stop_on_disconnect", "homing_direction", "clamping_travel", "model",
          "default_acceleration", "default_force_limit", "serial_number", "finger1", "finger2", "script",
          "auto_homing")

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


# JSON bodies: objects with the endpoints' field names and values of every JSON type (integers within
# the float range and shallow nesting: see fuzz/README.md for the open findings beyond that)
_scalar = st.one_of(st.none(), st.booleans(), st.integers(-(10**300), 10**300), st.floats(),
                    st.text(max_size=12), st.sampled_from(["wsg50", "fmf", "power", "current", "default", "ack"]))
_json = st.recursive(_scalar, lambda inner: st.one_of(st.lists(inner, max_size=4),
                                                     st.dictionaries(st.text(max_size=8), inner, max_size=4)),
                     max_leaves=12)
_body = st.one_of(
    st.dictionaries(st.sampled_from(FIELDS), _json, max_size=6),
    _json,
).map(lambda v: json.dumps(v).encode())
inputs = st.builds(lambda i, body: bytes([i]) + body, st.integers(0, 255), _body)


if __name__ == "__main__":
    main(test_one_input, inputs)
