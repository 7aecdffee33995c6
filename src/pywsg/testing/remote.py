"""The world of a ``wsg sim`` in another process, container or pod, over its HTTP world API.

::

    from pywsg.testing.remote import RemoteWorld

    world = RemoteWorld("http://127.0.0.1:8080", password="s3cret")
    world.place_part(22.0)
    print(world.state()["gripper_state"])

:class:`RemoteWorld` has the methods of the in-process :class:`pywsg.testing.World` (the same
:class:`~pywsg.testing.world.WorldActions`), so a test written against the ``wsg_sim`` fixture runs
against a container unchanged, except ``advance()``: a served gripper runs on its own clock.
Standard library only (urllib): no extra is needed.
"""

from __future__ import annotations

import json
import time
import urllib.error
import urllib.request
from typing import Any

from .world import HTTP_ROUTES, WorldActions, WorldError

__all__ = ["RemoteWorld", "wait_healthy"]

PREFIX = "/api/world"
HEALTH_PATH = "/healthz"
_ROUTE_OF = {action: (method, path, with_body) for method, path, action, with_body in HTTP_ROUTES}


class RemoteWorld(WorldActions):
    """The world API of the sim whose web interface is at ``web_url`` (``http://HOST:PORT``).

    ``password``: the sim's web password (``WSG_WEB_PASSWORD``), sent as ``Authorization: Bearer``;
    none is needed for a sim bound to loopback. ``timeout`` s per request. A refused value raises
    :class:`~pywsg.testing.world.WorldError` as in process; an unreachable sim raises ``OSError``.
    """

    def __init__(self, web_url: str, password: str | None = None, timeout: float = 5.0) -> None:
        self.base = web_url.rstrip("/")
        self.password = password
        self.timeout = timeout

    def _request(self, method: str, path: str, body: dict[str, Any] | None = None) -> dict[str, Any]:
        data = json.dumps(body).encode() if body is not None else None
        req = urllib.request.Request(self.base + PREFIX + path, data=data, method=method)
        if data is not None:
            req.add_header("Content-Type", "application/json")
        if self.password:
            req.add_header("Authorization", f"Bearer {self.password}")
        try:
            with urllib.request.urlopen(req, timeout=self.timeout) as reply:
                out: dict[str, Any] = json.loads(reply.read() or b"{}")
                return out
        except urllib.error.HTTPError as exc:
            try:
                detail = json.loads(exc.read() or b"{}")
            except ValueError:
                detail = {}
            errors = detail.get("errors") or {}
            if exc.code == 422 and errors:
                field, reason = next(iter(errors.items()))
                raise WorldError(field, str(reason)) from None
            raise WorldError("_", f"HTTP {exc.code}: {detail.get('detail', exc.reason)}") from None

    def _apply(self, action: str, **params: Any) -> str:
        method, path, with_body = _ROUTE_OF[action]
        body = {k: v for k, v in params.items() if v is not None} if with_body else None
        return str(self._request(method, path, body)["action"])

    def state(self) -> dict[str, Any]:
        """Gripper state, width, force, temperature, part, obstacle and faults (``GET /api/world``)."""
        return self._request("GET", "")

    @property
    def manual(self) -> bool:
        """Always False: a served gripper runs on its own (real or scaled) clock."""
        return False

    def advance(self, dt: float) -> float:
        raise RuntimeError("advance() needs a manual clock, which only an in-process sim has "
                           "(the wsg_sim fixture with clock='manual'); a served sim runs on its own clock")


def wait_healthy(web_url: str, timeout: float = 30.0, interval: float = 0.05) -> float:
    """Wait until ``GET web_url/healthz`` answers 200 (the sim is serving); returns the seconds waited.

    The probe opens no device session: it never raises FAST STOP nor takes a client's command
    interface. Raises TimeoutError after ``timeout`` s.
    """
    start = time.monotonic()
    url = web_url.rstrip("/") + HEALTH_PATH
    last: object = None
    while True:
        try:
            with urllib.request.urlopen(url, timeout=min(2.0, timeout)) as reply:
                if reply.status == 200:
                    return time.monotonic() - start
        except (OSError, ValueError) as exc:  # refused, reset, not yet HTTP
            last = exc
        if time.monotonic() - start > timeout:
            raise TimeoutError(f"{url} did not answer within {timeout:g} s (last: {last})")
        time.sleep(interval)
