"""The Commander's one gripper connection, through the public driver (:class:`pywsg.client.AsyncGripper`).

``CommanderSession`` holds what the page shows: the connection (URL, connected / lost and why),
the Communication Log (every frame both ways, from the driver's ``on_frame`` hook, decoded through
the catalog), the live state (auto-update streams 40h, 41h, 43h, 44h, 45h: change-only, every
``LIVE_PERIOD_S`` at most) and the results of the commands sent from the page. Everything is
numbered (``seq``) so the WebSocket sends only what a page has not seen yet.

Closing: :meth:`disconnect` ends the streams (over UDP and serial a subscription would outlive us),
then closes the driver, which announces the disconnect over TCP (07h, 000 §3.1.2) so the gripper
does not FAST STOP (000 §1.4.2). :meth:`page_left` does the same once no page has been open for
``grace`` seconds (a reload keeps the connection).
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import time
from collections import deque
from collections.abc import Callable
from typing import Any

from ...capture.commlog import LogEntry, summary
from ...client import AsyncGripper, AsyncStream, CommEntry, parse_url
from ...errors import TimeoutError, WsgError
from ...protocol import CATALOG, Frame, GripperState, Status, SystemFlag
from ...protocol.editor import PayloadSyntaxError, build_packet
from ..views import jsonable
from .commands import BY_KEY, coerce

log = logging.getLogger(__name__)

LIVE_PERIOD_S = 0.05
"""Auto-update period asked of the gripper (s): 20 Hz, as the web interface's live view."""
KEEP_FRAMES = 10_000
"""Frames the Communication Log keeps (older ones drop off; the saved files hold what is kept)."""
LIVE_STREAMS = ("system_state", "gripper_state", "width", "speed", "force")
Driver = Callable[..., AsyncGripper]


class CommandError(Exception):
    """A request the page sent that cannot be run: 409 (not connected) or 422 (bad values)."""

    def __init__(self, status: int, message: str, errors: dict[str, str] | None = None,
                 start: int | None = None, end: int | None = None) -> None:
        super().__init__(message)
        self.status = status
        self.errors = errors or {}
        self.start = start
        self.end = end


def _flag_names(flags: int) -> list[str]:
    return [f.name for f in SystemFlag if f.name and f.value and flags & f.value and f.value & (f.value - 1) == 0]


def log_row(seq: int, entry: LogEntry) -> dict[str, Any]:
    """A Communication Log line for the page: time, direction, ID, command, hex, status and values."""
    d = entry.decoded
    return {
        "seq": seq, "time": round(entry.time, 6), "direction": entry.direction, "id": d.command_id,
        "command": d.command, "hex": d.raw.hex(" ").upper(), "status": d.status, "status_code": d.status_code,
        "meaning": d.status_meaning, "text": summary(d), "error": d.error,
    }


class CommanderSession:
    """The gripper connection behind every open Commander page (one at a time, as the manual's tool)."""

    def __init__(self, *, driver: Driver = AsyncGripper, timeout: float = 3.0, grace: float = 1.0,
                 keep: int = KEEP_FRAMES) -> None:
        self.driver = driver
        self.timeout = timeout
        self.grace = grace
        self.gripper: AsyncGripper | None = None
        self.url: str | None = None
        self.status = "disconnected"  # connecting, connected, silent (no answer in time), lost, disconnected
        self.reason = ""
        self.log: deque[tuple[int, LogEntry]] = deque(maxlen=keep)
        self.log_seq = 0
        self.results: deque[dict[str, Any]] = deque(maxlen=200)
        self.result_seq = 0
        self.state: dict[str, Any] = {}
        self.state_seq = 0
        self.conn_seq = 0
        self.pages = 0
        self.last_rx = 0.0  # time.monotonic() of the last frame from the gripper
        self._streams: list[AsyncStream] = []
        self._tasks: set[asyncio.Task[Any]] = set()
        self._leave: asyncio.TimerHandle | None = None
        self._lock = asyncio.Lock()

    # -- what the page reads ---------------------------------------------------------------------
    def connection(self) -> dict[str, Any]:
        return {"status": self.status, "url": self.url, "reason": self.reason, "seq": self.conn_seq}

    def _set_status(self, status: str, reason: str = "") -> None:
        self.status, self.reason = status, reason
        self.conn_seq += 1

    def log_after(self, seq: int, limit: int = 500) -> list[dict[str, Any]]:
        rows = [log_row(s, e) for s, e in self.log if s > seq]
        return rows[-limit:]

    def results_after(self, seq: int) -> list[dict[str, Any]]:
        return [r for r in self.results if r["seq"] > seq]

    def entries(self) -> list[LogEntry]:
        return [e for _, e in self.log]

    def clear_log(self) -> None:
        self.log.clear()

    # -- the driver's hooks ----------------------------------------------------------------------
    def _on_frame(self, entry: CommEntry) -> None:
        if entry.frame is None:
            return  # a parse problem: the driver logs it; a checksum error fails the waiting call
        if entry.direction == "rx":
            self.last_rx = time.monotonic()
            if self.status == "silent":
                self._set_status("connected", "the gripper answers again")
        self.log_seq += 1
        self.log.append((self.log_seq, LogEntry.from_frame("tx" if entry.direction == "tx" else "rx",
                                                           entry.frame, entry.time)))

    def _on_lost(self, exc: BaseException | None) -> None:
        self._set_status("lost", f"connection to {self.url} lost" + (f": {exc}" if exc else ""))
        self._streams.clear()
        self.gripper = None

    def _record(self, command: str, status: str, final: bool, message: str = "", values: Any = None) -> dict[str, Any]:
        self.result_seq += 1
        r = {"seq": self.result_seq, "time": time.time(), "command": command, "status": status, "final": final,
             "message": message}
        if isinstance(values, SystemFlag):
            values = _flag_names(int(values))
        elif isinstance(values, bytes):
            values = values.hex(" ").upper()
        if values is not None:
            r["values"] = jsonable(values)
        self.results.append(r)
        return r

    def _failed(self, name: str, exc: WsgError, sent: float) -> dict[str, Any]:
        """A command's error as its result; a local timeout also marks the gripper as silent."""
        self._silent(exc, sent)
        status = exc.status.name if isinstance(exc.status, Status) else f"status {int(exc.status)}"
        return self._record(name, status, True, str(exc))

    def _silent(self, exc: WsgError, sent: float) -> bool:
        """No reply in time (not the gripper's E_TIMEOUT) and no frame at all since the request went out
        at ``sent`` (``time.monotonic()``): over UDP, serial and CAN there is no connection to lose, so
        this is how a gripper gone away shows; the next frame from it clears it."""
        if not isinstance(exc, TimeoutError) or exc.from_device or self.gripper is None:
            return False
        if self.last_rx >= sent:
            return False  # it did answer meanwhile (the driver took that for the late reply to an older request)
        self._set_status("silent", f"no answer from {self.url}: {exc}")
        return True

    # -- connecting ------------------------------------------------------------------------------
    async def connect(self, url: str) -> dict[str, Any]:
        """Connect to ``url`` (any form :func:`pywsg.client.parse_url` reads), replacing a connection."""
        try:
            endpoint = parse_url(url)
        except ValueError as exc:
            raise CommandError(422, str(exc), {"url": str(exc)}) from None
        async with self._lock:
            await self._close()
            self.url = str(endpoint)
            self._set_status("connecting")
            g = self.driver(endpoint, timeout=self.timeout, connect_timeout=self.timeout,
                            on_connection_lost=self._on_lost)
            g.on_frame = self._on_frame
            try:
                await g.connect()
            except (OSError, WsgError) as exc:
                self._set_status("disconnected", f"cannot connect to {self.url}: {exc}")
                raise CommandError(409, self.reason) from None
            self.gripper = g
            self._set_status("connected")
            started = time.monotonic()
            try:
                await self._start_live(g)
            except WsgError as exc:
                # the gripper refuses auto updates (commands still work), or does not answer at all
                if not self._silent(exc, started):
                    self._set_status("connected", f"no live state: {exc}")
        return self.connection()

    async def _start_live(self, g: AsyncGripper) -> None:
        for what in LIVE_STREAMS:
            stream = await g.subscribe(what, LIVE_PERIOD_S, change_only=True, maxlen=100)
            self._streams.append(stream)
            self._spawn(self._follow(stream))

    async def _follow(self, stream: AsyncStream) -> None:
        with contextlib.suppress(WsgError, asyncio.CancelledError):
            async for sample in stream:
                v = sample.value
                if isinstance(v, SystemFlag):
                    self.state["flags"] = _flag_names(int(v))
                    self.state["fast_stop"] = bool(v & SystemFlag.SF_FAST_STOP)
                    self.state["moving"] = bool(v & SystemFlag.SF_MOVING)
                    self.state["referenced"] = bool(v & SystemFlag.SF_REFERENCED)
                elif isinstance(v, GripperState):
                    self.state["gripper_state"] = v.name
                else:
                    key = {0x43: "width", 0x44: "speed", 0x45: "force"}.get(int(sample.command))
                    if key is None:
                        continue
                    self.state[key] = round(float(v), 3)
                self.state_seq += 1

    def _spawn(self, coro: Any) -> None:
        task = asyncio.get_running_loop().create_task(coro)
        self._tasks.add(task)
        task.add_done_callback(self._tasks.discard)

    async def disconnect(self, reason: str = "disconnected by the user") -> None:
        async with self._lock:
            await self._close()
            if self.url is not None:
                self._set_status("disconnected", reason)

    async def _close(self) -> None:
        g, self.gripper = self.gripper, None
        streams, self._streams = self._streams, []
        if g is None:
            return
        g.on_connection_lost = None
        if g.connected:
            for stream in streams:  # over UDP and serial a subscription outlives the client
                with contextlib.suppress(WsgError, OSError):
                    await stream.close()
        with contextlib.suppress(WsgError, OSError):
            await g.close()  # announces the disconnect over TCP (07h)
        for task in list(self._tasks):
            task.cancel()
        self.state = {}
        self.state_seq += 1

    # -- pages coming and going ------------------------------------------------------------------
    def page_opened(self) -> None:
        self.pages += 1
        if self._leave is not None:
            self._leave.cancel()
            self._leave = None

    def page_closed(self) -> None:
        """The last page gone for ``grace`` s: disconnect (07h over TCP), so the gripper does not FAST STOP."""
        self.pages -= 1
        if self.pages > 0 or self.gripper is None:
            return
        loop = asyncio.get_running_loop()
        self._leave = loop.call_later(self.grace, lambda: self._spawn(self._left()))

    async def _left(self) -> None:
        self._leave = None
        if self.pages == 0:
            await self.disconnect("the Commander page was closed")

    # -- commands --------------------------------------------------------------------------------
    def _driver_or_fail(self) -> AsyncGripper:
        g = self.gripper
        if g is None or not g.connected:
            raise CommandError(409, "not connected: connect to a gripper first (Gripper → Connect)")
        return g

    async def run(self, key: str, given: dict[str, Any]) -> dict[str, Any]:
        """Run the predefined command ``key`` with the page's values; its result (final for all but motions)."""
        p = BY_KEY.get(key)
        if p is None:
            raise CommandError(404, f"no predefined command {key!r}")
        values, errors = coerce(p, given)
        if errors:
            raise CommandError(422, "invalid input: " + "; ".join(f"{k}: {v}" for k, v in errors.items()), errors)
        g = self._driver_or_fail()
        name = CATALOG[p.command].name
        sent = time.monotonic()
        try:
            got = await p.call(g, values)
        except WsgError as exc:
            return self._failed(name, exc, sent)
        except ValueError as exc:  # the driver refused a value before sending
            raise CommandError(422, str(exc), {"_": str(exc)}) from None
        if p.motion:
            self._spawn(self._settle(name, got))
            return self._record(name, "E_CMD_PENDING", False, "running: the final reply follows")
        return self._record(name, "E_SUCCESS", True, values=got)

    async def _settle(self, name: str, motion: Any) -> None:
        sent = time.monotonic()
        try:
            await motion.wait()
        except WsgError as exc:
            self._failed(name, exc, sent)
        else:
            self._record(name, "E_SUCCESS", True, "done")

    async def send_custom(self, command: str, payload: str) -> dict[str, Any]:
        """The Custom Command Editor's Send: the packet as shown, through the driver's raw request."""
        packet = parse_packet(command, payload)
        g = self._driver_or_fail()
        name = CATALOG[packet.command_id].name if packet.command_id in CATALOG else f"{packet.command_id:02X}h"
        self._spawn(self._custom(g, name, packet.command_id, packet.payload))
        return {"wire": packet.wire.hex(" ").upper(), "command": name}

    async def _custom(self, g: AsyncGripper, name: str, cid: int, payload: bytes) -> None:
        self._record(name, "sent", False, "sent from the Custom Command Editor")
        sent = time.monotonic()
        try:
            reply = await g.request(cid, payload, check=False)
        except WsgError as exc:
            self._failed(name, exc, sent)
            return
        status = reply.status.name if isinstance(reply.status, Status) else f"status {int(reply.status)}"
        self._record(name, status, True, Status.describe(int(reply.status)) if reply.status != Status.E_SUCCESS
                     else "", reply.params.hex(" ").upper() or None)

    async def close(self) -> None:
        """Stop everything (the server is stopping): disconnect first."""
        if self._leave is not None:
            self._leave.cancel()
        await self.disconnect("the Commander stopped")


def parse_packet(command: str, payload: str) -> Any:
    """The editor's packet, or CommandError 422 naming the field and the place of the bad item."""
    try:
        return build_packet(command, payload)
    except PayloadSyntaxError as exc:
        field = "payload" if exc.start is not None or not _id_ok(command) else "id"
        raise CommandError(422, str(exc), {field: str(exc)}, exc.start, exc.end) from None


def _id_ok(command: str) -> bool:
    from ...protocol.editor import parse_command_id

    try:
        parse_command_id(command)
    except PayloadSyntaxError:
        return False
    return True


def preview(command: str, payload: str) -> dict[str, Any]:
    """What the editor shows while the user types: the packet's parts, each item's bytes, the decoding."""
    from ...protocol.decode import decode_frame
    from ...protocol.editor import parse_command_id, parse_items

    out: dict[str, Any] = {"ok": False}
    try:
        cid = parse_command_id(command)
    except PayloadSyntaxError as exc:
        out.update(field="id", error=str(exc))
        return out
    try:
        items = parse_items(payload)
    except PayloadSyntaxError as exc:
        out.update(field="payload", error=str(exc), start=exc.start, end=exc.end)
        return out
    data = b"".join(i.data for i in items)
    frame = Frame(cid, data)
    wire = frame.encode()
    d = decode_frame(frame, "request")
    out.update(
        ok=True, id=cid, command=d.command, wire=wire.hex(" ").upper(), size=len(data),
        preamble=wire[:3].hex(" ").upper(), header=wire[3:6].hex(" ").upper(), payload=data.hex(" ").upper(),
        crc=wire[-2:].hex(" ").upper(), decoded=summary(d),
        items=[{"text": i.text, "start": i.start, "end": i.end, "hex": i.data.hex(" ").upper()} for i in items],
    )
    return out
