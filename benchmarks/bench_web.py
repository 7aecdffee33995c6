"""Web interface figures: cost of one live update, HTTP request rate, WebSocket rate with many clients.

The gripper, its runner, a Modbus/TCP server and the web interface run in a background thread (own
event loop, as in ``wsg sim``); clients run in the main thread.

    .venv/bin/python benchmarks/bench_web.py [--requests 2000] [--seconds 3]
"""

from __future__ import annotations

import argparse
import asyncio
import json
import threading
import time

import httpx
import websockets

from pywsg.device import VirtualGripper
from pywsg.fieldbus.modbus.server import serve_modbus
from pywsg.server import DeviceRunner
from pywsg.web.app import serve_web
from pywsg.web.fieldbus_view import fieldbus_view
from pywsg.web.views import state_view


def per_update_cost(n: int = 5000) -> tuple[float, float]:
    """µs for one WebSocket message body: state only, and state + fieldbus registers."""
    from pywsg.fieldbus.controller import FieldbusController

    g = VirtualGripper("wsg50")
    ctl = FieldbusController(g)
    t0 = time.perf_counter()
    for _ in range(n):
        json.dumps({"type": "update", "t": 0.0, "state": state_view(g.snapshot())})
    state = (time.perf_counter() - t0) / n * 1e6
    t0 = time.perf_counter()
    for _ in range(n):
        json.dumps({"type": "update", "t": 0.0, "state": state_view(g.snapshot()), "fieldbus": fieldbus_view(ctl)})
    both = (time.perf_counter() - t0) / n * 1e6
    return state, both


class Server:
    def __init__(self) -> None:
        self.loop = asyncio.new_event_loop()
        threading.Thread(target=self.loop.run_forever, daemon=True).start()
        asyncio.run_coroutine_threadsafe(self._start(), self.loop).result(10)

    async def _start(self) -> None:
        self.gripper = VirtualGripper("wsg50")
        self.runner = DeviceRunner(self.gripper)
        self.runner.start()
        self.modbus = await serve_modbus(self.gripper, "127.0.0.1", 0)
        self.web = await serve_web(self.gripper, "127.0.0.1", 0, fieldbus=self.modbus.controller)
        self.cpu0 = 0.0

    def cpu(self) -> float:
        return asyncio.run_coroutine_threadsafe(self._cpu(), self.loop).result(5)

    async def _cpu(self) -> float:
        return time.thread_time()


def http_rate(url: str, n: int) -> tuple[float, float]:
    """GET /api/state and POST /api/stop (CSRF-checked, through the binary protocol): requests/s."""
    with httpx.Client(base_url=url) as c:
        token = c.get("/api/csrf").json()["token"]
        t0 = time.perf_counter()
        for _ in range(n):
            c.get("/api/state")
        get = n / (time.perf_counter() - t0)
        t0 = time.perf_counter()
        for _ in range(n):
            c.post("/api/stop", headers={"X-CSRF-Token": token})
        post = n / (time.perf_counter() - t0)
    return get, post


async def ws_rate(url: str, clients: int, seconds: float, fieldbus: bool) -> float:
    """Messages per second per client over ``seconds`` with ``clients`` connected."""
    q = "?fieldbus=1" if fieldbus else ""
    counts = [0] * clients

    async def one(i: int) -> None:
        async with websockets.connect(url + q) as ws:
            end = time.monotonic() + seconds
            while time.monotonic() < end:
                await ws.recv()
                counts[i] += 1

    await asyncio.gather(*(one(i) for i in range(clients)))
    return sum(counts) / clients / seconds


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--requests", type=int, default=2000)
    ap.add_argument("--seconds", type=float, default=3.0)
    args = ap.parse_args()
    state, both = per_update_cost()
    print(f"one live update body: {state:.0f} µs (state), {both:.0f} µs (state + fieldbus registers)")
    srv = Server()
    url = f"http://127.0.0.1:{srv.web.port}"
    get, post = http_rate(url, args.requests)
    print(f"HTTP keep-alive, one client: GET /api/state {get:,.0f} req/s, POST /api/stop {post:,.0f} req/s")
    ws = url.replace("http", "ws") + "/ws"
    for clients, fb in ((1, False), (8, False), (32, False), (32, True)):
        c0, w0 = srv.cpu(), time.perf_counter()
        rate = asyncio.run(ws_rate(ws, clients, args.seconds, fb))
        load = (srv.cpu() - c0) / (time.perf_counter() - w0)
        print(f"WebSocket {clients:2d} clients{' + fieldbus' if fb else '           '}: "
              f"{rate:5.1f} msg/s per client (target 20), server thread CPU {load * 100:4.0f} %")


if __name__ == "__main__":
    main()
