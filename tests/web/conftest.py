"""Web interface test harness: a real virtual gripper on real sockets, a real browser.

``LiveSim`` runs the gripper, its runner, the TCP command interface, the Modbus/TCP fieldbus server
and the web interface on an asyncio loop in a background thread, the way ``wsg sim`` runs them;
tests talk to it over 127.0.0.1 like a user would (httpx, raw TCP, pymodbus, Chromium). Device
calls from a test go through ``sim.call`` so that the gripper is only touched by its own loop.
"""

from __future__ import annotations

import asyncio
import hashlib
import json
import os
import socket
import struct
import threading
import time
from collections.abc import Callable, Iterator
from concurrent.futures import Future
from pathlib import Path
from typing import Any, TypeVar

import httpx
import pytest

from pywsg.device import Settings, VirtualGripper
from pywsg.fieldbus.modbus.server import serve_modbus
from pywsg.protocol import Frame
from pywsg.server import DeviceRunner, TcpServer
from pywsg.web.app import WebHandle, serve_web

ARTIFACTS = Path(__file__).resolve().parents[2] / "test-artifacts" / "web"
DOC_IMAGES = Path(__file__).resolve().parents[2] / "docs" / "img"
DOC_IMAGES_MANIFEST = DOC_IMAGES / "screenshots.json"
CHROMIUM = os.environ.get("PYWSG_CHROMIUM", "/usr/bin/chromium")
CHROMIUM_ARGS = [
    "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run", "--disable-background-networking",
    "--disable-component-update", "--disable-sync", "--disable-dev-shm-usage",
]
T = TypeVar("T")
REMOTE_PASSWORD = "correct horse battery"


def new_loop(kind: str) -> asyncio.AbstractEventLoop:
    """``"default"``: the loop ``wsg sim`` runs on as shipped (uvloop when installed, as ``[web]`` does);
    ``"asyncio"``: stock asyncio (``wsg sim --no-uvloop``)."""
    if kind == "default":
        try:
            import uvloop
        except ImportError:  # pragma: no cover - [web] brings it
            pass
        else:
            return uvloop.new_event_loop()
    return asyncio.new_event_loop()


class LiveSim:
    """One virtual gripper served on TCP, Modbus/TCP and the web interface, in a loop thread.

    ``loop``: ``"asyncio"`` (stock) or ``"default"`` (as shipped: uvloop when installed). The shared
    per-module sim runs on the default loop, the others on stock asyncio, so the web tests meet both. An
    exception the loop reports (``Exception in callback ...``, which ``wsg sim`` would print as a
    traceback) fails the test at close.
    """

    def __init__(self, tmp: Path, host: str = "127.0.0.1", loop: str = "asyncio", **web_kwargs: Any) -> None:
        self.settings_path = tmp / "settings.json"
        self.loop = new_loop(loop)
        self.loop_errors: list[str] = []
        self.loop.set_exception_handler(
            lambda _loop, context: self.loop_errors.append(f"{context.get('message')}: {context.get('exception')!r}"))
        self.thread = threading.Thread(target=self.loop.run_forever, name="live-sim", daemon=True)
        self.thread.start()
        self.web_kwargs = web_kwargs
        self.host = host
        self.run(self._start())

    async def _start(self) -> None:
        self.gripper = VirtualGripper("wsg50", settings=Settings())
        self.runner = DeviceRunner(self.gripper)
        self.runner.start()
        self.tcp = await TcpServer(self.gripper, self.runner, "127.0.0.1", 0).start()
        self.modbus = await serve_modbus(self.gripper, "127.0.0.1", 0)
        sim_info = {"TCP": f"tcp://127.0.0.1:{self.tcp.port}", "Modbus/TCP": f"127.0.0.1:{self.modbus.port}"}
        kwargs: dict[str, Any] = {"fieldbus": self.modbus.controller, "sim_info": sim_info,
                                  "settings_path": self.settings_path}
        kwargs.update(self.web_kwargs)
        self._serve_kwargs = kwargs
        self.web: WebHandle = await serve_web(self.gripper, self.host, 0, **kwargs)

    def stop_web(self) -> int:
        """Stop the web interface (as when the simulator stops); its port, for ``start_web``."""
        port = self.web.port
        self.run(self.web.close())
        return port

    def start_web(self, port: int) -> None:
        """Serve the web interface again on ``port``: a new app, so every session is gone (a restart)."""
        self.web = self.run(serve_web(self.gripper, self.host, port, **self._serve_kwargs))

    @property
    def url(self) -> str:
        return f"http://127.0.0.1:{self.web.port}"

    def run(self, coro: Any, timeout: float = 10.0) -> Any:
        return asyncio.run_coroutine_threadsafe(coro, self.loop).result(timeout)

    def call(self, fn: Callable[..., T], *args: Any, **kwargs: Any) -> T:
        """Run ``fn`` on the loop thread (the gripper is not thread-safe) and return its result."""
        fut: Future[T] = Future()

        def job() -> None:
            try:
                fut.set_result(fn(*args, **kwargs))
            except BaseException as exc:
                fut.set_exception(exc)

        self.loop.call_soon_threadsafe(job)
        return fut.result(5.0)

    def snapshot(self) -> Any:
        return self.call(self.gripper.snapshot)

    def loop_cpu(self) -> float:
        """CPU seconds of the loop thread (the web interface, the gripper and its servers), so far."""
        return self.call(time.thread_time)

    def __enter__(self) -> LiveSim:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        async def stop() -> None:
            await self.web.close()
            await self.modbus.close()
            await self.tcp.close()
            self.runner.stop()

        try:
            self.run(stop())
        finally:
            self.loop.call_soon_threadsafe(self.loop.stop)
            self.thread.join(5)
            self.loop.close()
        assert not self.loop_errors, f"the sim's loop reported exceptions: {self.loop_errors}"


def record_doc_image(name: str, version: str) -> None:
    """Note in docs/img/screenshots.json that docs/img/``name`` shows pywsg ``version`` (and its SHA-256)."""
    manifest = json.loads(DOC_IMAGES_MANIFEST.read_text()) if DOC_IMAGES_MANIFEST.exists() else {}
    digest = hashlib.sha256((DOC_IMAGES / name).read_bytes()).hexdigest()
    manifest[name] = {"pywsg": version, "sha256": digest}
    DOC_IMAGES_MANIFEST.write_text(json.dumps(manifest, indent=2, sort_keys=True) + "\n")


def raw_get(port: int, path: str) -> bytes:
    """A bare ``GET path`` request to 127.0.0.1:``port``, as bytes to pipeline or flood with."""
    return f"GET {path} HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\n\r\n".encode()


def client_for(sim: LiveSim) -> httpx.Client:
    """An HTTP client with a session cookie and its CSRF token in the default headers."""
    c = httpx.Client(base_url=sim.url, timeout=30.0)  # generous: a loaded machine, not a hang
    token = c.get("/api/csrf").json()["token"]
    c.headers["X-CSRF-Token"] = token
    return c


@pytest.fixture(scope="module")
def _module_live_sim(tmp_path_factory: pytest.TempPathFactory) -> Iterator[LiveSim]:
    with LiveSim(tmp_path_factory.mktemp("websim"), loop="default") as s:
        yield s


@pytest.fixture
def sim(_module_live_sim: LiveSim) -> Iterator[LiveSim]:
    """One LiveSim per test module, checked after each test: a test that leaves a FAST STOP behind
    fails itself, and the FAST STOP is acknowledged so the next test starts clean."""
    yield _module_live_sim
    if _module_live_sim.snapshot().fast_stop:
        _module_live_sim.call(_module_live_sim.gripper.acknowledge_fast_stop)
        pytest.fail("the test left the shared sim in FAST STOP (acknowledged now for the next test)")


@pytest.fixture
def api(sim: LiveSim) -> Iterator[httpx.Client]:
    c = client_for(sim)
    try:
        yield c
    finally:
        c.close()


@pytest.fixture(scope="module")
def browser() -> Iterator[Any]:
    """One headless Chromium per test module (Debian's chromium, driven by Playwright)."""
    if not Path(CHROMIUM).exists():
        pytest.fail(f"{CHROMIUM} missing: scripts/test.sh installs Debian's chromium package")
    from playwright.sync_api import sync_playwright

    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    with sync_playwright() as p:
        b = p.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS, headless=True)
        try:
            yield b
        finally:
            b.close()


@pytest.fixture
def page(browser: Any) -> Iterator[Any]:
    """A fresh browser context (no cookies) and page; JavaScript errors fail the test."""
    # bypass_csp: Playwright evaluates wait_for_function strings with eval, which our CSP forbids
    context = browser.new_context(viewport={"width": 1400, "height": 950}, bypass_csp=True)
    pg = context.new_page()
    errors: list[str] = []
    pg.on("pageerror", lambda exc: errors.append(str(exc)))
    pg.set_default_timeout(30_000)  # ms; generous: a loaded machine, not a hang
    yield pg
    context.close()
    assert not errors, f"JavaScript errors: {errors}"


@pytest.fixture(scope="module")
def remote(tmp_path_factory: pytest.TempPathFactory) -> Iterator[LiveSim]:
    """Bound to 0.0.0.0 with a password: the non-loopback rules (tests use it over 127.0.0.1)."""
    with LiveSim(tmp_path_factory.mktemp("remote"), host="0.0.0.0", password=REMOTE_PASSWORD) as s:
        yield s


def submit_form(page: Any, form: str, **values: str) -> None:
    """Fill the named inputs of ``form`` (a CSS selector) and press its submit button."""
    for name, value in values.items():
        page.fill(f"{form} [name={name}]", value)
    page.click(f"{form} button[type=submit]")


def home(sim: LiveSim, api: httpx.Client) -> None:
    """Reference the gripper (homing) and wait until it is done."""
    r = api.post("/api/home", json={})
    assert r.status_code == 202, r.text
    wait_for(lambda: sim.snapshot().referenced and not sim.snapshot().moving, 60.0)


def wait_for(cond: Callable[[], bool], timeout: float = 30.0, step: float = 0.02) -> None:
    import time

    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if cond():
            return
        time.sleep(step)
    import inspect

    try:
        what = inspect.getsource(cond).strip()
    except (OSError, TypeError):
        what = repr(cond)
    raise AssertionError(f"not met within {timeout:g} s: {what}")


def read_frame(s: socket.socket) -> Frame:
    """Read one whole frame (preamble, header, payload, CRC: 000 §1.2.1) from a raw TCP socket."""
    head = b""
    while len(head) < 6:
        head += s.recv(6 - len(head))
    size = struct.unpack_from("<H", head, 4)[0]
    rest = b""
    while len(rest) < size + 2:
        rest += s.recv(size + 2 - len(rest))
    return Frame(head[3], rest[:size])


def read_status(s: socket.socket) -> str:
    """Read one whole frame from a raw TCP socket and return its status name."""
    status = read_frame(s).status
    return status.name if hasattr(status, "name") else str(status)
