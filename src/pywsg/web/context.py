"""What every part of the web interface shares: the device session, the log feed, the context.

``WebContext`` is the one object the routers (``pages``, ``login``, ``api``, ``sim_api``, ``live``)
are built around: the gripper, the session store (``security.Auth``), the web interface's own device
session (``CommandBridge``: request frames in, status codes out), the numbered system log
(``LogFeed``) and what the simulator serves. ``error()`` and ``command_result()`` are the one JSON
error style: ``{"detail": ..., "errors": {field: reason}}``. Nothing here registers a route.
"""

from __future__ import annotations

import asyncio
import contextlib
import dataclasses
import re
import time
from collections import deque
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from fastapi.responses import JSONResponse

from ..device.clock import real_seconds
from ..protocol import CATALOG, Command, DeviceType, Frame, Status
from .security import Auth
from .views import jsonable, state_view

UPDATE_PERIOD_S = 0.05  # 20 Hz WebSocket updates
MAX_BODY = 64 * 1024  # bytes of a request body, checked while it streams (security.BodyLimit)


class InputError(Exception):
    """A value the device cannot take: 422 with a message per field."""

    def __init__(self, errors: dict[str, str]) -> None:
        super().__init__("; ".join(f"{k}: {v}" for k, v in errors.items()))
        self.errors = errors


def error(status: int, detail: str, errors: Mapping[str, str] | None = None,
          headers: Mapping[str, str] | None = None) -> JSONResponse:
    """The one JSON error style: ``{"detail": text, "errors": {field: reason}}``."""
    body: dict[str, Any] = {"detail": detail}
    if errors is not None:
        body["errors"] = dict(errors)
    return JSONResponse(body, status_code=status, headers=dict(headers) if headers else None)


# -- the device side ------------------------------------------------------------------------------
class CommandBridge:
    """The web interface's own device session: request frames in, status codes out."""

    def __init__(self, gripper: Any) -> None:
        self.gripper = gripper
        self.results: deque[dict[str, Any]] = deque(maxlen=100)
        self.seq = 0
        self.last_seq = 0  # seq of the last answer ``send`` recorded: the page matches final results to it
        self.session = gripper.open_session("web", peer="web interface", deliver=self._deliver)

    def _record(self, command_id: int, status: Status | int, final: bool) -> dict[str, Any]:
        self.seq += 1
        name = Status(status).name if isinstance(status, Status) else f"status {int(status)}"
        entry = {"seq": self.seq, "time": time.time(), "command": CATALOG[command_id].name
                 if command_id in CATALOG else f"{command_id:02X}h", "status": name, "final": final}
        self.results.append(entry)
        return entry

    def _deliver(self, frame: Frame) -> None:
        """Deferred frames of this session: final replies of motions started here."""
        if len(frame.payload) >= 2:
            self._record(frame.command_id, frame.status, True)

    def send(self, command: Command, *, record: bool = True, **values: Any) -> tuple[Status | int, dict[str, Any]]:
        """Send one request; (status of the immediate reply, decoded reply values).

        ``record``: list it under the Control Panel's command results (not for internal queries).
        """
        spec = CATALOG[command]
        frame = Frame(int(command), spec.encode_request(values))
        replies = self.gripper.handle_frame(self.session, frame)
        answer: tuple[Status | int, dict[str, Any]] | None = None
        for reply in replies:
            if reply.command_id == int(command) and answer is None:
                status, decoded = spec.decode_reply(reply.payload)
                if record:
                    self.last_seq = self._record(int(command), status, status != Status.E_CMD_PENDING)["seq"]
                answer = status, dict(decoded)
            else:  # e.g. Stop: the aborted motion's final frame comes with 22h's own reply
                self._deliver(reply)
        if answer is None:
            raise RuntimeError(f"no reply to {spec.label}")
        return answer

    def limits(self) -> dict[str, float]:
        """53h Get System Limits: stroke mm, speeds mm/s, accelerations mm/s², forces N."""
        status, values = self.send(Command.GET_SYSTEM_LIMITS, record=False)
        if status != Status.E_SUCCESS:
            return {}
        return {k: float(v) for k, v in values.items() if isinstance(v, int | float)}

    def device_type(self) -> DeviceType | None:
        status, values = self.send(Command.GET_SYSTEM_INFO, record=False)
        t = values.get("type")
        return t if status == Status.E_SUCCESS and isinstance(t, DeviceType) else None

    def close(self) -> None:
        with contextlib.suppress(Exception):
            self.gripper.close_session(self.session)


class LogFeed:
    """The device's system log, numbered for incremental reads (``after=seq``)."""

    def __init__(self, system_log: Any, clock: Callable[[], float] | None = None, size: int = 2000) -> None:
        self.entries: deque[dict[str, Any]] = deque(maxlen=size)
        self.seq = 0
        self.clock = clock
        if system_log is None:
            return
        for entry in existing_entries(system_log):
            self.add(entry)
        add_listener = getattr(system_log, "add_listener", None)
        if callable(add_listener):
            add_listener(self.add)

    def add(self, entry: Any) -> None:
        self.seq += 1
        data = jsonable(entry) if dataclasses.is_dataclass(entry) else {}
        for name in ("time", "level", "message"):
            if name not in data:
                data[name] = jsonable(getattr(entry, name, "" if name != "time" else None))
        if not data.get("message"):
            data["message"] = str(entry)
        data["seq"] = self.seq
        # entry times are device-clock seconds; the page shows wall-clock time
        t = data.get("time")
        wall = time.time()
        if isinstance(t, int | float) and self.clock is not None:
            with contextlib.suppress(Exception):
                wall -= max(0.0, real_seconds(self.clock, float(self.clock()) - t))  # --time-scale K
        data["wall_time"] = wall
        self.entries.append(data)

    def after(self, seq: int, limit: int = 500) -> list[dict[str, Any]]:
        out = [e for e in self.entries if e["seq"] > seq]
        return out[-limit:]


def existing_entries(system_log: Any) -> list[Any]:
    for name in ("entries", "records", "items"):
        got = getattr(system_log, name, None)
        if callable(got):
            got = got()
        if got is not None:
            try:
                return list(got)
            except TypeError:
                pass
    try:
        return list(system_log)
    except TypeError:
        return []


@dataclasses.dataclass
class WebContext:
    gripper: Any
    auth: Auth
    bridge: CommandBridge
    log_feed: LogFeed
    fieldbus: Any = None
    sim_info: Any = None
    settings_path: Path | None = None
    closing: asyncio.Event = dataclasses.field(default_factory=asyncio.Event)
    live_clients: int = 0
    _cache: dict[str, tuple[float, Any]] = dataclasses.field(default_factory=dict)

    def cached(self, key: str, make: Callable[[], Any], max_age: float = UPDATE_PERIOD_S / 2) -> Any:
        """One computation per update period shared by all live clients (32 clients, one snapshot)."""
        now = time.monotonic()
        hit = self._cache.get(key)
        if hit is not None and now - hit[0] < max_age:
            return hit[1]
        value = make()
        self._cache[key] = (now, value)
        return value

    def model_name(self) -> str:
        try:
            t = self.bridge.device_type()
        except Exception:
            t = None
        if t is None or t == DeviceType.UNKNOWN:
            return "WSG"
        return re.sub(r"^([A-Z]+)(\d+)$", r"\1 \2", t.name)

    def state(self) -> dict[str, Any]:
        return state_view(self.gripper.snapshot())

    def has_faults(self) -> bool:
        return getattr(self.gripper, "faults", None) is not None


def command_result(command: Command, status: Status | int, values: Mapping[str, Any] | None = None,
                   seq: int | None = None) -> JSONResponse:
    """200 E_SUCCESS, 202 E_CMD_PENDING (final result follows on the WebSocket), 409 device refusal.

    ``seq``: the number of this result in ``CommandBridge.results``; a final result with a higher
    number for the same command settles it, even when the WebSocket brought it before this reply.
    """
    name = status.name if isinstance(status, Status) else f"status {int(status)}"
    body: dict[str, Any] = {
        "command": CATALOG[command].name, "status": name, "code": int(status), "seq": seq,
        "message": status.description if isinstance(status, Status) else "unknown status code",
    }
    if values:
        body["values"] = jsonable(dict(values))
    if status == Status.E_SUCCESS:
        return JSONResponse(body)
    if status == Status.E_CMD_PENDING:
        return JSONResponse(body, status_code=202)
    body["detail"] = f"{CATALOG[command].name} refused by the device: {body['message']} ({name})"
    return JSONResponse(body, status_code=409)


def _check_range(errors: dict[str, str], name: str, value: float, low: float | None, high: float | None,
                 unit: str) -> None:
    if (low is not None and value < low) or (high is not None and value > high):
        lo = "" if low is None else f"{low:g}"
        hi = "" if high is None else f"{high:g}"
        errors[name] = f"must be between {lo} and {hi} {unit}".replace("between  and", "at most")


def motion_ranges(lim: Mapping[str, float]) -> dict[str, tuple[float, float, str]]:
    """(low, high, unit) a web form accepts for width, speed and force, from the 53h limits.

    The Control Panel shows these beside its fields and ``motion_limits`` refuses outside them,
    so the hint ("allowed 5 … 120 N") and the refusal ("must be between 5 and 120 N") agree.
    """
    out: dict[str, tuple[float, float, str]] = {}
    if "stroke" in lim:
        out["width"] = (0.0, lim["stroke"], "mm")
    if "max_speed" in lim:
        out["speed"] = (lim.get("min_speed", 0.0), lim["max_speed"], "mm/s")
    if "ovr_force" in lim or "nom_force" in lim:
        out["force"] = (lim.get("min_force", 0.0), max(lim.get("ovr_force", 0.0), lim.get("nom_force", 0.0)), "N")
    return out


def motion_limits(ctx: WebContext, width: float | None, speed: float | None, force: float | None = None,
                  relative: bool = False) -> None:
    """Raise InputError naming each value outside ``motion_ranges`` (mm, mm/s, N)."""
    ranges = motion_ranges(ctx.bridge.limits())
    errors: dict[str, str] = {}
    for name, value in (("width", width), ("speed", speed), ("force", force)):
        if value is None or name not in ranges:
            continue
        low, high, unit = ranges[name]
        if name == "width" and relative:
            low = -high
        _check_range(errors, name, value, low, high, unit)
    if errors:
        raise InputError(errors)
