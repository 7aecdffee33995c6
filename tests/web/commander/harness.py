"""The Commander under test: ``wsg commander``'s server on a loop thread, a ``wsg sim`` to drive, a wire tap.

``Cmdr`` serves the Commander (``serve_commander``) on 127.0.0.1:0 in a background loop, as the CLI
does; tests reach it over HTTP/WebSocket like a browser. ``WireTap`` records the bytes the sim's
gripper is fed (TCP and serial: ``feed``; UDP: ``handle_datagram``), exactly as they arrived, so a
test can compare them with the packet the Custom Command Editor showed.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import httpx

from pywsg.testing.host import LoopThread, SimThread
from pywsg.web.commander import CommanderHandle, CommanderSession, serve_commander


class Cmdr:
    """A running Commander (``url``), its session, and an HTTP client with the CSRF token set."""

    def __init__(self, grace: float = 0.2, host: str = "127.0.0.1", **kwargs: Any) -> None:
        self.loop = LoopThread("commander")
        self.session: CommanderSession = self.loop.run(self._session(grace))
        self.handle: CommanderHandle = self.loop.run(serve_commander(host, 0, session=self.session, **kwargs))
        self.url = f"http://127.0.0.1:{self.handle.port}"
        self.http = httpx.Client(base_url=self.url, timeout=30.0,
                                 transport=_Diagnosed(self.loop, httpx.HTTPTransport(), self._driver_report))
        token = self.http.get("/api/csrf").json().get("token")  # None off loopback until a login
        if token:
            self.http.headers["X-CSRF-Token"] = token

    @staticmethod
    async def _session(grace: float) -> CommanderSession:
        return CommanderSession(grace=grace, timeout=3.0)

    def _driver_report(self) -> str:
        """The session's status and its driver's request timer (for a hung request's report)."""
        g = self.session.gripper
        head = f"session: {self.session.status} {self.session.reason!r}\n"
        if g is None:
            return head + "no driver\n"
        return head + (f"driver: timer {g._timer} due {g._timer_at:.3f}, now {time.monotonic():.3f}, "
                       f"waiting {[(w.command_id, w.done, round(w.deadline, 3)) for w in g._timed]}, "
                       f"replies { {k: len(v) for k, v in g._demux.replies.items()} }\n")

    def connect(self, url: str) -> dict[str, Any]:
        r = self.http.post("/api/connect", json={"url": url})
        assert r.status_code == 200, r.text
        return dict(r.json())

    def state(self) -> dict[str, Any]:
        return dict(self.http.get("/api/state").json())

    def close(self) -> None:
        try:
            self.http.close()
            self.loop.run(self.handle.close())
        finally:
            self.loop.close()

    def __enter__(self) -> Cmdr:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def await_chain(coro: Any) -> list[str]:
    """Where a suspended coroutine waits, innermost last: each coroutine it awaits, with file and line."""
    lines: list[str] = []
    while coro is not None and len(lines) < 60:
        frame = getattr(coro, "cr_frame", None) or getattr(coro, "ag_frame", None) or getattr(coro, "gi_frame", None)
        if frame is not None:
            lines.append(f"{frame.f_code.co_filename}:{frame.f_lineno} in {frame.f_code.co_name}")
        nxt = getattr(coro, "cr_await", None) or getattr(coro, "ag_await", None) or getattr(coro, "gi_yieldfrom", None)
        if nxt is None and not hasattr(coro, "cr_frame"):
            lines.append(repr(coro))  # a Future or another awaitable: the end of the chain
        coro = nxt
    return lines


def loop_report(lt: LoopThread) -> str:
    """What the loop thread is doing: its thread's stack and every task's stack (a hung request's report)."""
    import asyncio
    import io
    import sys
    import traceback

    out = io.StringIO()
    frame = sys._current_frames().get(lt._thread.ident or -1)
    out.write("loop thread stack:\n" + "".join(traceback.format_stack(frame)) if frame else "no loop thread\n")
    try:  # read from this thread while the loop runs: good enough for a failure report
        tasks = list(asyncio.all_tasks(lt.loop))
    except RuntimeError as exc:
        tasks = []
        out.write(f"tasks not listed: {exc}\n")
    for task in tasks:
        out.write(f"\n{task!r}\n")
        out.write("".join(f"  {line}\n" for line in await_chain(task.get_coro())))
    return out.getvalue()


class _Diagnosed(httpx.BaseTransport):
    """httpx's transport; a request that times out fails with what the Commander's loop was doing."""

    def __init__(self, lt: LoopThread, inner: httpx.BaseTransport, extra: Callable[[], str]) -> None:
        self.lt, self.inner, self.extra = lt, inner, extra

    def handle_request(self, request: httpx.Request) -> httpx.Response:
        try:
            return self.inner.handle_request(request)
        except httpx.TimeoutException as exc:
            try:
                extra = self.extra()
            except Exception as err:  # a report of a report: never hide the timeout
                extra = f"(no driver report: {err!r})\n"
            raise AssertionError(f"{request.method} {request.url.path}: {exc}\n{extra}{loop_report(self.lt)}") from exc

    def close(self) -> None:
        self.inner.close()


class WireTap:
    """Every chunk of bytes the sim's gripper 0 received, as received (TCP and serial reads, UDP datagrams)."""

    def __init__(self, sim: SimThread) -> None:
        self.chunks: list[bytes] = []
        g = sim.gripper

        def wrap(name: str) -> None:
            original: Callable[..., Any] = getattr(g, name)

            def tapped(session: Any, data: bytes) -> Any:
                self.chunks.append(bytes(data))
                return original(session, data)

            setattr(g, name, tapped)

        sim.call(lambda: (wrap("feed"), wrap("handle_datagram")))

    @property
    def data(self) -> bytes:
        return b"".join(self.chunks)

    def clear(self) -> None:
        self.chunks.clear()
