"""``wsg proxy --control PORT``: switch the proxy's network faults at runtime over HTTP.

The routes are the network part of the sim's world API (:mod:`pywsg.web.world_api`), so one client
serves both: ``wsg world --sim http://127.0.0.1:PORT net latency --ms 200``::

    GET    /api/world        {"net": {...faults on...}, "counts": {...}}
    POST   /api/world/net    {"kind": "latency", "ms": 200, "jitter": 50, "on": true}
    DELETE /api/world/net    every network fault off

Replies are JSON (``{"ok": true, "action": "latency 200 ms ± 50 ms", "state": {"net": ...}}``); a refused
value is 422 ``{"detail": ..., "errors": {field: reason}}``. Like the world API on a loopback sim it is
for programs on this host and has no password: it binds loopback only, the ``Host`` header must name a
loopback address, a request a browser page sends (``Origin`` / ``Sec-Fetch-Site``) is refused (403),
bodies are at most 4 KiB and a connection that sends nothing for 5 s is closed.

Served by the standard library's :class:`http.server.ThreadingHTTPServer` on a thread of its own; each
change runs on the proxy's loop (the faults are only touched there).
"""

from __future__ import annotations

import asyncio
import ipaddress
import json
import socket
import threading
from collections.abc import Callable
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from typing import Any

from ..server.netfault import NetFaultError, NetFaults

__all__ = ["ControlServer"]

MAX_BODY = 4096
def _is_loopback(host: str) -> bool:
    """``localhost``, any of 127.0.0.0/8 or ::1 (``127.0.0.9`` too: a second proxy's control port)."""
    if host.lower() == "localhost":
        return True
    try:
        return ipaddress.ip_address(host.strip("[]")).is_loopback
    except ValueError:
        return False


class _Server(ThreadingHTTPServer):
    daemon_threads = True


class _Server6(_Server):
    address_family = socket.AF_INET6


def _host_name(header: str) -> str:
    if header.startswith("["):
        return header[1:].split("]", 1)[0]
    return header.rsplit(":", 1)[0] if header.count(":") == 1 else header


class ControlServer:
    """HTTP control of ``net`` on ``host:port`` (0: any free port; read :attr:`port`)."""

    def __init__(self, net: NetFaults, loop: asyncio.AbstractEventLoop, host: str = "127.0.0.1",
                 port: int = 0) -> None:
        host = host.strip("[]")
        if not _is_loopback(host):
            raise ValueError(f"{host}: the control API has no password, so it listens on loopback only "
                             "(127.0.0.1, ::1, localhost)")
        self.net = net
        self.loop = loop
        server = _Server6 if ":" in host else _Server  # ::1: an IPv6 socket (the default is IPv4 only)
        self.httpd = server((host, port), self._handler())
        self.port = int(self.httpd.server_address[1])
        self.host = host
        self._thread = threading.Thread(target=self.httpd.serve_forever, name="pywsg-proxy-control", daemon=True)

    @property
    def url(self) -> str:
        return f"http://[{self.host}]:{self.port}" if ":" in self.host else f"http://{self.host}:{self.port}"

    def start(self) -> ControlServer:
        self._thread.start()
        return self

    def close(self) -> None:
        self.httpd.shutdown()
        self.httpd.server_close()
        self._thread.join(5)

    def _on_loop(self, fn: Callable[[], dict[str, Any]]) -> dict[str, Any]:
        async def run() -> dict[str, Any]:
            return fn()

        return asyncio.run_coroutine_threadsafe(run(), self.loop).result(5)

    def _state(self) -> dict[str, Any]:
        return {"net": self.net.state(), "counts": dict(self.net.counts)}

    def _handler(self) -> type[BaseHTTPRequestHandler]:
        control = self

        class Handler(BaseHTTPRequestHandler):
            server_version = "pywsg-proxy"
            timeout = 5  # s a connection may stay silent (a slow or idle client frees its thread)

            def log_message(self, format: str, *args: Any) -> None:
                pass  # the proxy's own output is the comm log

            def _reply(self, status: int, body: dict[str, Any]) -> None:
                data = json.dumps(body).encode()
                self.send_response(status)
                self.send_header("Content-Type", "application/json")
                self.send_header("Content-Length", str(len(data)))
                self.end_headers()
                self.wfile.write(data)

            def _refused(self) -> bool:
                if self.headers.get("Origin") is not None or self.headers.get("Sec-Fetch-Site", "none") != "none":
                    self._reply(403, {"detail": "the control API is for programs, not browser pages"})
                    return True
                if not _is_loopback(_host_name(self.headers.get("Host", ""))):
                    self._reply(403, {"detail": "Host header must name a loopback address"})
                    return True
                if self.path.rstrip("/") not in ("/api/world", "/api/world/net"):
                    self._reply(404, {"detail": f"{self.path}: not found (GET /api/world, POST/DELETE /api/world/net)"})
                    return True
                return False

            def do_GET(self) -> None:
                if not self._refused():
                    self._reply(200, control._on_loop(control._state))

            def do_DELETE(self) -> None:
                if self._refused():
                    return
                text = control._on_loop(lambda: {"action": control.net.clear()})["action"]
                self._reply(200, {"ok": True, "action": text, "state": control._on_loop(control._state)})

            def do_POST(self) -> None:
                if self._refused():
                    return
                length = self.headers.get("Content-Length", "0")
                if not length.isdigit() or int(length) > MAX_BODY:
                    self._reply(413, {"detail": f"request body larger than {MAX_BODY} bytes"})
                    return
                try:
                    params = json.loads(self.rfile.read(int(length)) or b"{}")
                except (ValueError, UnicodeDecodeError, RecursionError):  # RecursionError: nesting 1,000+ deep
                    self._reply(422, {"detail": "invalid input: body is not JSON", "errors": {"_": "not JSON"}})
                    return
                if not isinstance(params, dict):
                    self._reply(422, {"detail": "invalid input: body must be a JSON object",
                                      "errors": {"_": "not an object"}})
                    return
                kind = str(params.pop("kind", ""))

                def change() -> dict[str, Any]:
                    if kind == "clear":
                        return {"action": control.net.clear()}
                    try:
                        return {"action": control.net.set(kind, params)}
                    except NetFaultError as exc:
                        return {"error": (exc.field, exc.reason)}

                out = control._on_loop(change)
                if "error" in out:
                    field, reason = out["error"]
                    self._reply(422, {"detail": f"invalid input: {field}: {reason}", "errors": {field: reason}})
                    return
                self._reply(200, {"ok": True, "action": out["action"], "state": control._on_loop(control._state)})

        return Handler
