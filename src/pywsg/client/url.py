"""Endpoint URLs: ``tcp://host[:1000]``, ``udp://host[:1500]?reply_port=1501``,
``serial:///dev/ttyUSB0?baudrate=115200``, ``can://can0?interface=socketcan&bitrate=500000``."""

from __future__ import annotations

from dataclasses import dataclass, field
from urllib.parse import parse_qs, unquote, urlsplit

DEFAULT_TCP_PORT = 1000
DEFAULT_UDP_PORT = 1500
DEFAULT_UDP_REPLY_PORT = 1501
DEFAULT_BAUDRATE = 115200
DEFAULT_CAN_REQUEST_ID = 0x01  # inferred, see docs/driver.md "CAN"
DEFAULT_CAN_REPLY_ID = 0x02
CAN_OPTIONS = ("interface", "bitrate", "request_id", "reply_id", "extended")


@dataclass(frozen=True)
class Endpoint:
    """A parsed endpoint.

    ``scheme``: ``tcp``, ``udp`` or ``serial``. For tcp/udp ``host`` and ``port``; for udp also
    ``reply_port`` (the local port the gripper sends its replies to; 0 = any free port, replies
    expected at our source address). For serial ``path`` (device file) and ``baudrate``. For can
    ``path`` (the python-can channel), ``interface`` (python-can interface; "" = python-can's own
    configuration), ``bitrate`` (bit/s, 0 = the interface's setting), ``request_id`` / ``reply_id``
    (CAN identifiers of requests and of replies), ``extended`` (29-bit identifiers) and ``can_options``
    (further keyword arguments for ``can.Bus``, as strings).
    """

    scheme: str
    host: str = ""
    port: int = 0
    reply_port: int = DEFAULT_UDP_REPLY_PORT
    path: str = ""
    baudrate: int = DEFAULT_BAUDRATE
    bind: str = ""
    interface: str = ""
    bitrate: int = 0
    request_id: int = DEFAULT_CAN_REQUEST_ID
    reply_id: int = DEFAULT_CAN_REPLY_ID
    extended: bool = False
    can_options: tuple[tuple[str, str], ...] = field(default=())

    def __str__(self) -> str:
        if self.scheme == "can":
            q = [f"interface={self.interface}"] if self.interface else []
            q += [f"bitrate={self.bitrate}"] if self.bitrate else []
            q += [f"request_id=0x{self.request_id:X}", f"reply_id=0x{self.reply_id:X}"]
            q += ["extended=1"] if self.extended else []
            q += [f"{k}={v}" for k, v in self.can_options]
            return f"can://{self.path}?{'&'.join(q)}"
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


def _can_id(query: dict[str, list[str]], key: str, default: int, extended: bool, url: str) -> int:
    if key not in query:
        return default
    raw = query[key][-1]
    try:
        value = int(raw, 0)
    except ValueError:
        raise ValueError(f"{key}={raw!r} in {url!r} is not an integer (e.g. 0x01)") from None
    top = 0x1FFFFFFF if extended else 0x7FF
    if not 0 <= value <= top:
        raise ValueError(f"{key}={raw} in {url!r} is not a {'29' if extended else '11'}-bit CAN identifier")
    return value


def _parse_can(url: str, netloc: str, path: str, query: dict[str, list[str]]) -> Endpoint:
    channel = unquote(netloc + path)
    if not channel:
        raise ValueError(f"no CAN channel in {url!r} (e.g. can://can0?interface=socketcan)")
    ext_raw = query.get("extended", ["0"])[-1].lower()
    if ext_raw not in ("0", "1", "true", "false", "yes", "no"):
        raise ValueError(f"extended={ext_raw!r} in {url!r}: use 0 or 1")
    extended = ext_raw in ("1", "true", "yes")
    req = _can_id(query, "request_id", DEFAULT_CAN_REQUEST_ID, extended, url)
    rep = _can_id(query, "reply_id", DEFAULT_CAN_REPLY_ID, extended, url)
    if req == rep:
        raise ValueError(f"request_id and reply_id in {url!r} are the same identifier 0x{req:X}")
    extra = tuple((k, v[-1]) for k, v in sorted(query.items()) if k not in CAN_OPTIONS)
    return Endpoint("can", path=channel, interface=query.get("interface", [""])[-1],
                    bitrate=_int(query, "bitrate", 0, url), request_id=req, reply_id=rep, extended=extended,
                    can_options=extra)


def parse_url(url: str) -> Endpoint:
    """Parse an endpoint URL. A bare ``host[:port]`` means TCP. Raises ValueError on bad input."""
    if "://" not in url:
        url = "tcp://" + url
    parts = urlsplit(url)
    scheme = parts.scheme.lower()
    query = parse_qs(parts.query, keep_blank_values=True)
    if scheme == "can":  # other options go to python-can's Bus (e.g. fd, data_bitrate, receive_own_messages)
        return _parse_can(url, parts.netloc, parts.path, query)
    known = {"tcp": {"bind"}, "udp": {"reply_port", "bind"}, "serial": {"baudrate", "baud"}}
    if scheme not in known:
        raise ValueError(f"unsupported scheme {scheme!r} in {url!r} (use tcp://, udp://, serial:// or can://)")
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
