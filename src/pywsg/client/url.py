"""Endpoint URLs: ``tcp://host[:1000]``, ``udp://host[:1500]?reply_port=1501``,
``serial:///dev/ttyUSB0?baudrate=115200``."""

from __future__ import annotations

from dataclasses import dataclass
from urllib.parse import parse_qs, urlsplit

DEFAULT_TCP_PORT = 1000
DEFAULT_UDP_PORT = 1500
DEFAULT_UDP_REPLY_PORT = 1501
DEFAULT_BAUDRATE = 115200


@dataclass(frozen=True)
class Endpoint:
    """A parsed endpoint.

    ``scheme``: ``tcp``, ``udp`` or ``serial``. For tcp/udp ``host`` and ``port``; for udp also
    ``reply_port`` (the local port the gripper sends its replies to; 0 = any free port, replies
    expected at our source address). For serial ``path`` (device file) and ``baudrate``.
    """

    scheme: str
    host: str = ""
    port: int = 0
    reply_port: int = DEFAULT_UDP_REPLY_PORT
    path: str = ""
    baudrate: int = DEFAULT_BAUDRATE
    bind: str = ""

    def __str__(self) -> str:
        if self.scheme == "serial":
            return f"serial://{self.path}?baudrate={self.baudrate}"
        host = f"[{self.host}]" if ":" in self.host else self.host
        if self.scheme == "udp":
            return f"udp://{host}:{self.port}?reply_port={self.reply_port}"
        return f"{self.scheme}://{host}:{self.port}"


def _int(query: dict[str, list[str]], key: str, default: int, url: str) -> int:
    if key not in query:
        return default
    raw = query[key][-1]
    try:
        value = int(raw)
    except ValueError:
        raise ValueError(f"{key}={raw!r} in {url!r} is not an integer") from None
    if value < 0:
        raise ValueError(f"{key}={value} in {url!r} is negative")
    return value


def parse_url(url: str) -> Endpoint:
    """Parse an endpoint URL. A bare ``host[:port]`` means TCP. Raises ValueError on bad input."""
    if "://" not in url:
        url = "tcp://" + url
    parts = urlsplit(url)
    scheme = parts.scheme.lower()
    query = parse_qs(parts.query, keep_blank_values=True)
    known = {"tcp": {"bind"}, "udp": {"reply_port", "bind"}, "serial": {"baudrate", "baud"}}
    if scheme not in known:
        raise ValueError(f"unsupported scheme {scheme!r} in {url!r} (use tcp://, udp:// or serial://)")
    unknown = set(query) - known[scheme]
    if unknown:
        raise ValueError(f"unknown option(s) {', '.join(sorted(unknown))} in {url!r}")
    if scheme == "serial":
        path = (parts.netloc + parts.path) if parts.netloc else parts.path
        if not path:
            raise ValueError(f"no device path in {url!r} (e.g. serial:///dev/ttyUSB0)")
        baud = _int(query, "baudrate", _int(query, "baud", DEFAULT_BAUDRATE, url), url)
        if baud == 0:
            raise ValueError(f"baudrate 0 in {url!r}")
        return Endpoint("serial", path=path, baudrate=baud)
    try:
        port = parts.port
    except ValueError as exc:
        raise ValueError(f"bad port in {url!r}: {exc}") from None
    host = parts.hostname or ""
    if not host:
        raise ValueError(f"no host in {url!r}")
    bind = query.get("bind", [""])[-1]
    if scheme == "udp":
        reply = _int(query, "reply_port", DEFAULT_UDP_REPLY_PORT, url)
        if reply > 65535:
            raise ValueError(f"reply_port {reply} in {url!r} is not a port")
        return Endpoint("udp", host=host, port=DEFAULT_UDP_PORT if port is None else port,
                        reply_port=reply, bind=bind)
    return Endpoint("tcp", host=host, port=DEFAULT_TCP_PORT if port is None else port, bind=bind)
