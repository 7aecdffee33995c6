"""The live WebSocket ``/ws``: ~20 Hz updates of state, log, command results and fieldbus.

One message per update period (``context.UPDATE_PERIOD_S``): ``{"type": "update", "t", "state",
"log"?, "results"?, "fieldbus"?}``; the snapshot is computed once per period for all clients
(``WebContext.cached``). At most ``MAX_LIVE_CLIENTS`` at once (close code 1013 beyond). Reading
rules as for the pages; the Origin must name this server (close code 1008 otherwise).
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import time
from typing import Any

from fastapi import APIRouter, WebSocket

from .auth import same_origin
from .context import UPDATE_PERIOD_S, WebContext
from .fieldbus_view import fieldbus_view
from .security import COOKIE_NAME

MAX_LIVE_CLIENTS = 32  # WebSocket clients per interface: each costs a snapshot every 50 ms
WS_MAX_MESSAGE = 4096
"""Bytes a client's WebSocket message may have (uvicorn closes with 1009 past it). The pages send nothing
on /ws; uvicorn's default of 16 MiB let 32 clients x 15 MiB take RSS 108 -> 680 MB."""
WS_MESSAGES_PER_S, WS_MESSAGE_BURST = 10.0, 20
"""Messages a client may send on /ws (a token bucket), past it the socket is closed with 1008: reading
1 MiB of small messages cost 0.74-1.41 s of CPU for nothing."""


def router(ctx: WebContext) -> APIRouter:
    r = APIRouter()

    @r.websocket("/ws")
    async def live(websocket: WebSocket) -> None:
        """~20 Hz: state, new log entries, new command results, and (``?fieldbus=1``) the registers."""
        if not await accept_live(websocket, ctx.auth, ctx.live_clients >= MAX_LIVE_CLIENTS, "too many live clients"):
            return
        ctx.live_clients += 1
        q = websocket.query_params
        want_fieldbus = q.get("fieldbus") == "1"
        log_after = _int(q.get("log"), ctx.log_feed.seq)
        # a page passes the last result it saw; a larger number than ours is from before a restart
        results_after = min(_int(q.get("results"), ctx.bridge.seq), ctx.bridge.seq)
        closed = asyncio.create_task(_wait_closed(websocket))
        try:
            while not ctx.closing.is_set() and not closed.done():
                msg: dict[str, Any] = {"type": "update", "t": time.time(), "state": ctx.cached("state", ctx.state)}
                entries = ctx.log_feed.after(log_after)
                if entries:
                    msg["log"] = entries
                    log_after = entries[-1]["seq"]
                results = [e for e in ctx.bridge.results if e["seq"] > results_after]
                if results:
                    msg["results"] = results
                    results_after = results[-1]["seq"]
                if want_fieldbus:
                    msg["fieldbus"] = ctx.cached("fieldbus", lambda: fieldbus_view(ctx.fieldbus))
                await websocket.send_text(json.dumps(msg, allow_nan=False))
                await asyncio.wait([closed], timeout=UPDATE_PERIOD_S)
        except Exception:  # the client went away mid-send: nothing to clean up but the task
            pass
        finally:
            ctx.live_clients -= 1
            closed.cancel()
            with contextlib.suppress(Exception):
                await websocket.close()

    return r


async def accept_live(websocket: WebSocket, auth: Any, full: bool, reason: str) -> bool:
    """Accept a page's live WebSocket: a session that may read, from this origin (else close 1008), and
    room for one more (``full``: close 1013 with ``reason``, try again later). True when accepted."""
    s = auth.lookup(websocket.cookies.get(COOKIE_NAME))
    if not auth.may_read(s) or not same_origin(websocket):
        await websocket.close(code=1008)
        return False
    await websocket.accept()
    if full:
        await websocket.close(code=1013, reason=reason)
        return False
    return True


async def _wait_closed(websocket: WebSocket) -> None:
    """Read until the client goes; a client sending more than the page ever does (nothing) is closed."""
    loop = asyncio.get_running_loop()
    tokens, last = float(WS_MESSAGE_BURST), loop.time()
    with contextlib.suppress(Exception):
        while True:
            message = await websocket.receive()
            if message.get("type") == "websocket.disconnect":
                return
            now = loop.time()
            tokens = min(float(WS_MESSAGE_BURST), tokens + (now - last) * WS_MESSAGES_PER_S)
            last = now
            if tokens < 1.0:
                await websocket.close(code=1008, reason="too many messages (the live feed takes none)")
                return
            tokens -= 1.0


def _int(text: str | None, default: int) -> int:
    try:
        return int(text) if text is not None else default
    except ValueError:
        return default
