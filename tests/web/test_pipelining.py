"""Pipelined HTTP costs at most the keep-alive budget per connection (issue 23 item 15).

A client pipelining 1 MiB of ``GET /api/world`` (or 404s) on one connection made the server run
every request: 22 / 37 s of CPU per MiB. Now the connection's budget of requests is answered, the
last with ``Connection: close``, the rest is dropped unparsed and the connection closes. The cost is
the loop thread's CPU time, compared with a baseline of the same number of ordinary requests
measured in the same test, never with absolute seconds.
"""

from __future__ import annotations

import socket
import time
from collections.abc import Iterator

import pytest

from .conftest import LiveSim, client_for, raw_get

MIB = 1 << 20
BUDGET = 100  # serve_web's default requests_per_connection


@pytest.fixture(scope="module")
def sim(tmp_path_factory: pytest.TempPathFactory) -> Iterator[LiveSim]:
    """Without the per-client rate limit (tests/web/test_request_rate.py): these floods come from one
    address, and the limit would answer 429 long before the keep-alive budget tested here."""
    with LiveSim(tmp_path_factory.mktemp("pipelining"), request_rate=None) as s:
        yield s


def _pipeline(port: int, blob: bytes, timeout: float) -> bytes:
    """Send ``blob`` in one go on a new connection; everything the server sends until it closes.

    ``timeout`` bounds the whole exchange (the pre-fix server took minutes for 1 MiB)."""
    deadline = time.monotonic() + timeout
    got = bytearray()
    with socket.create_connection(("127.0.0.1", port), timeout=timeout) as s:
        s.setblocking(False)
        view = memoryview(blob)
        while time.monotonic() < deadline:
            if view:
                try:
                    view = view[s.send(view):]
                except (BlockingIOError, InterruptedError):
                    pass
                except (BrokenPipeError, ConnectionResetError):
                    view = view[:0]  # the server closed: read what it answered
            try:
                data = s.recv(65536)
            except (BlockingIOError, InterruptedError):
                time.sleep(0.001)
                continue
            except ConnectionResetError:
                break
            if not data:
                break
            got += data
    return bytes(got)


@pytest.mark.parametrize("path", ["/api/world", "/no/such/page"], ids=["world", "404"])
def test_one_mebibyte_of_pipelined_requests_costs_one_budget(sim: LiveSim, path: str) -> None:
    port = sim.web.port
    one = raw_get(port, path)
    # baseline: the budget's worth of the same request, pipelined the same way
    t0 = sim.loop_cpu()
    base_answer = _pipeline(port, one * BUDGET, timeout=60.0)
    base = sim.loop_cpu() - t0
    assert base_answer.count(b"HTTP/1.1 ") == BUDGET, "the baseline answers every request of the budget"

    t0 = sim.loop_cpu()
    answer = _pipeline(port, one * (MIB // len(one)), timeout=max(60.0, 40 * base))
    flood = sim.loop_cpu() - t0
    answers = answer.count(b"HTTP/1.1 ")
    # the budget is answered, in order, the last one announcing the close; nothing after it
    assert answers == BUDGET, f"{answers} answers to {MIB // len(one)} pipelined requests"
    last_head = answer[answer.rindex(b"HTTP/1.1 "):].split(b"\r\n\r\n", 1)[0].lower()
    assert b"connection: close" in last_head
    # 1 MiB is ~20,000 requests: unbounded it costs ~200x the baseline; reading and dropping the rest
    # of the megabyte is allowed a few baselines
    assert flood < 4 * base + 0.05, f"1 MiB pipelined cost {flood:.3f} s CPU, {BUDGET} requests {base:.3f} s"


def test_ordinary_keep_alive_use_is_not_cut(sim: LiveSim) -> None:
    """Fewer requests than the budget on one connection: all answered, the connection stays open."""
    port = sim.web.port
    with socket.create_connection(("127.0.0.1", port), timeout=30.0) as s:
        for _ in range(3):
            s.sendall(raw_get(port, "/api/world") * 10)
            got = b""
            while got.count(b"HTTP/1.1 200") < 10:
                data = s.recv(65536)
                assert data, "the server closed a connection under its budget"
                got += data
            assert b"connection: close" not in got.lower()


def test_the_budgets_last_request_is_answered_when_its_body_comes_after_its_headers(sim: LiveSim) -> None:
    """The request that spends the budget is a POST whose body arrives in a later packet (as httpx and
    browsers send it): its body is read and it is answered, with ``Connection: close``. Before, the
    body was dropped as if pipelined after the budget, and the request hung until the client gave up
    (a Commander command, every 100th request of a page's connection)."""
    port = sim.web.port
    c = client_for(sim)
    cookie = "; ".join(f"{name}={value}" for name, value in c.cookies.items())
    token = c.headers["X-CSRF-Token"]
    c.close()
    body = b'{"width": "wide"}'  # read and refused by the route: 422 names the field
    head = (f"POST /api/move HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nCookie: {cookie}\r\nX-CSRF-Token: {token}\r\n"
            f"Content-Type: application/json\r\nContent-Length: {len(body)}\r\n\r\n").encode()
    got = bytearray()
    with socket.create_connection(("127.0.0.1", port), timeout=30.0) as s:
        s.sendall(raw_get(port, "/api/world") * (BUDGET - 1))
        while got.count(b"HTTP/1.1 200") < BUDGET - 1:
            data = s.recv(65536)
            assert data, "the server closed the connection under its budget"
            got += data
        s.sendall(head)
        time.sleep(0.2)  # the body in a packet of its own
        s.sendall(body)
        while data := s.recv(65536):  # a hang here is the defect (the 30 s socket timeout fails the test)
            got += data
    last = bytes(got[got.rindex(b"HTTP/1.1 "):])
    assert last.startswith(b"HTTP/1.1 422"), last[:300]
    assert b"connection: close" in last.split(b"\r\n\r\n", 1)[0].lower() and b"width" in last
