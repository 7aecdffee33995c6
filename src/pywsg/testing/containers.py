"""A virtual gripper in a container, for tests: a testcontainers module (``pip install 'pywsg[containers]'``).

::

    from pywsg import Gripper
    from pywsg.testing.containers import WsgSimContainer

    with WsgSimContainer() as sim:                 # image pywsg-sim:<version> (scripts/build-image.sh)
        sim.world.place_part(22.0)
        with Gripper(sim.url) as g:
            g.home(); g.grip(22.0, speed=100)

It works with a Docker or a Podman socket (``DOCKER_HOST=unix:///run/podman/podman.sock``; see
docs/container.md for testcontainers' settings with Podman). ``start()`` returns once the gripper
serves, found out through the web interface's ``/healthz``: no TCP connection is opened and dropped (a
connection closed without 07h is a FAST STOP, 000 §3.1.2). Ports are published on the host's
loopback address only. The web password is made per container (``.password``) unless given.
"""

from __future__ import annotations

import os
import secrets
from typing import Any, cast

from testcontainers.core.container import DockerContainer

from .. import __version__
from .remote import RemoteWorld, wait_healthy

__all__ = ["DEFAULT_IMAGE", "WsgSimContainer"]

DEFAULT_IMAGE = os.environ.get("WSG_SIM_IMAGE", f"pywsg-sim:{__version__}")
"""The image ``scripts/build-image.sh`` tags (``WSG_SIM_IMAGE`` overrides)."""

TCP, UDP, WEB, MODBUS = 1000, 1500, 8080, 502
"""The image's ports inside the container (TCP command interface, UDP, web, Modbus/TCP)."""


class WsgSimContainer(DockerContainer):
    """``wsg sim`` in a container: ``.url`` (TCP), ``.udp_url``, ``.web_url``, ``.modbus_url``, ``.world``.

    ``model``, ``count`` (grippers: ports 1000+i, 1500+i and 8080+i inside), ``time_scale`` (K times
    real time), ``modbus`` (serve Modbus/TCP on 502), ``password`` (the web and world API password;
    default: a fresh random one), ``ulimits`` (``{"nofile": 4096}``: hosts whose default limits exceed
    the hard limits, as rootful Podman on some CI machines, need them explicit). Further keyword
    arguments go to :class:`testcontainers.core.container.DockerContainer`.
    """

    def __init__(self, image: str = DEFAULT_IMAGE, *, model: str = "wsg50", count: int = 1, time_scale: float = 1.0,
                 modbus: bool = False, password: str | None = None, ulimits: dict[str, int] | None = None,
                 startup_timeout: float = 60.0, **kwargs: Any) -> None:
        super().__init__(image, **kwargs)
        self.password = password or secrets.token_urlsafe(16)
        self.count = count
        self.startup_timeout = startup_timeout
        self.start_seconds: float | None = None
        """Seconds from the container's start until the gripper served (``/healthz`` answered)."""
        self.with_env("WSG_WEB_PASSWORD", self.password)
        self.with_env("WSG_SIM_MODEL", model)
        self.with_env("WSG_SIM_COUNT", str(count))
        self.with_env("WSG_SIM_TIME_SCALE", repr(float(time_scale)))
        self._modbus = modbus
        if modbus:
            self.with_env("WSG_SIM_MODBUS_PORT", str(MODBUS))
        for i in range(count):
            for port, proto in ((TCP, "tcp"), (UDP, "udp"), (WEB, "tcp"), *(((MODBUS, "tcp"),) if modbus else ())):
                # on the host's loopback only, any free port (docker-py's (ip,) form; testcontainers types
                # the value as a port number only)
                self.ports[f"{port + i}/{proto}"] = cast(Any, ("127.0.0.1",))
        if ulimits:
            from docker.types import Ulimit

            self._kwargs["ulimits"] = [Ulimit(name=k, soft=v, hard=v) for k, v in ulimits.items()]

    def start(self) -> WsgSimContainer:
        """Start the container and return once every gripper's web interface answers ``/healthz``."""
        super().start()
        try:
            self.start_seconds = sum(wait_healthy(self.web_url_of(i), self.startup_timeout) for i in range(self.count))
        except TimeoutError as exc:
            logs = self.get_wrapped_container().logs().decode("utf-8", "replace")
            raise TimeoutError(f"{exc}; the container said:\n{logs}") from None
        return self

    def _port(self, port: int, proto: str = "tcp") -> int:
        client = self.get_docker_client().client.api
        mapping = client.port(self.get_container_id(), f"{port}/{proto}")
        if not mapping:
            raise ConnectionError(f"port {port}/{proto} of the container is not published")
        return int(mapping[0]["HostPort"])

    @property
    def host(self) -> str:
        """The address the published ports are reached at."""
        host: str = self.get_container_host_ip()
        return "127.0.0.1" if host == "localhost" else host

    def url_of(self, i: int) -> str:
        """Gripper ``i``'s TCP command interface, ``tcp://HOST:PORT``."""
        return f"tcp://{self.host}:{self._port(TCP + i)}"

    def udp_url_of(self, i: int) -> str:
        """Gripper ``i``'s UDP command interface; it answers the sender's port (``reply_port=0``)."""
        return f"udp://{self.host}:{self._port(UDP + i, 'udp')}?reply_port=0"

    def web_url_of(self, i: int) -> str:
        return f"http://{self.host}:{self._port(WEB + i)}"

    def world_of(self, i: int) -> RemoteWorld:
        """Gripper ``i``'s world (the in-process fixture's World methods, over HTTP)."""
        return RemoteWorld(self.web_url_of(i), self.password)

    @property
    def url(self) -> str:
        """Gripper 0's TCP command interface."""
        return self.url_of(0)

    @property
    def udp_url(self) -> str:
        return self.udp_url_of(0)

    @property
    def web_url(self) -> str:
        return self.web_url_of(0)

    @property
    def modbus_url(self) -> str:
        """Gripper 0's Modbus/TCP server, ``HOST:PORT`` (only with ``modbus=True``)."""
        if not self._modbus:
            raise RuntimeError("start the container with modbus=True")
        return f"{self.host}:{self._port(MODBUS)}"

    @property
    def world(self) -> RemoteWorld:
        return self.world_of(0)
