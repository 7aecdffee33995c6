"""Network faults between a gripper and its clients, switchable at runtime (like Toxiproxy's toxics).

One :class:`NetFaults` per virtual gripper (:func:`net_faults`) or per ``wsg proxy``. The sim's
transports and the proxy pass the gripper's outgoing bytes through a :class:`Shaper` and ask
:meth:`NetFaults.lose` / :meth:`NetFaults.garble_bytes` about incoming ones; with every fault off the
hooks are one attribute test, so a healthy link costs nothing.

=============  ==========================================================  ======================
fault          what the client sees                                         interfaces
=============  ==========================================================  ======================
``latency``    each reply ``ms`` later (± ``jitter`` ms, order kept on TCP) TCP, UDP, serial, proxy
``bandwidth``  replies trickle at ``rate`` bytes/s                          TCP, UDP, serial, proxy
``slicer``     replies cut into ``size``-byte segments, ``gap`` ms apart    TCP, serial, proxy
``reset``      TCP connections reset (RST) ``timeout`` s after they open    TCP, proxy
               (those already open: after the switch)
``silent``     nothing at all: requests are not executed, no replies;       TCP, UDP, serial, proxy
               the connection stays open (closed after ``timeout`` s > 0)
``drop``       each datagram lost with probability ``p`` (both directions) UDP, proxy (UDP)
``reorder``    a reply datagram held back, sent after the next one (``p``)  UDP, proxy (UDP)
``garble``     each byte flipped with probability ``p`` (both directions)  serial, TCP, UDP, proxy
=============  ==========================================================  ======================

On CAN (:mod:`pywsg.server.can_bus`) each 8-byte CAN frame counts as a datagram (drop, reorder,
latency, garble, silent); Modbus/TCP has none of these hooks.

Times of the network are real seconds (``time.monotonic``), not the gripper's clock: a manual or
scaled gripper clock does not slow down or speed up the wire. Random choices come from one
``random.Random(seed)`` per :class:`NetFaults` (``seed`` 0 unless given), so a test run repeats.
"""

from __future__ import annotations

import asyncio
import collections
import math
import random
import re
import weakref
from collections.abc import Callable, Mapping
from dataclasses import dataclass, fields, replace
from typing import Any

__all__ = ["KINDS", "NetFaultError", "NetFaults", "Shaper", "net_faults"]

KINDS = ("latency", "bandwidth", "slicer", "reset", "silent", "drop", "reorder", "garble")
"""The network fault kinds (``wsg world net KIND``, world action ``net``)."""

REORDER_HOLD = 0.05
"""Longest time (s) a held-back datagram waits for a next one before it goes out anyway."""

MAX_PENDING = 64 * 1024
"""Bytes one :class:`Shaper` holds back at most (latency, bandwidth, slicer); what would exceed it is
dropped whole, as by a congested link (``counts["overflow"]``), so a slow fault never grows memory."""


class NetFaultError(ValueError):
    """A network fault was refused: ``field`` names the parameter, the message says why."""

    def __init__(self, field: str, reason: str) -> None:
        super().__init__(f"{field}: {reason}")
        self.field = field
        self.reason = reason


@dataclass
class _Settings:
    """What is switched on. Times in s, rate in bytes/s, probabilities 0..1; 0 means off."""

    latency: float = 0.0
    jitter: float = 0.0
    rate: float = 0.0
    slice_size: int = 0
    slice_delay: float = 0.0
    reset: float | None = None
    silent: bool = False
    close_after: float = 0.0
    drop: float = 0.0
    reorder: float = 0.0
    garble: float = 0.0


def _show(value: Any) -> str:
    """``repr`` cut short: a refused value may be a 400-digit number."""
    text = repr(value) if not isinstance(value, int) or value.bit_length() < 64 else "a huge integer"
    return text if len(text) <= 40 else text[:37] + "..."


def _num(params: Mapping[str, Any], name: str, default: float, lo: float = 0.0, hi: float = math.inf) -> float:
    """A JSON number within ``lo..hi``. Strings are refused, as by every world route (``"1_0"`` is not
    10): the command line's ``--net`` turns its text into numbers first (:func:`parse_number`)."""
    value = params.get(name, default)
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise NetFaultError(name, f"must be a number, not {_show(value)}")
    try:
        out = float(value)
    except OverflowError:  # an integer beyond any float
        raise NetFaultError(name, f"must be within {lo:g}..{hi:g}, not {_show(value)}") from None
    if not (math.isfinite(out) and lo <= out <= hi):
        raise NetFaultError(name, f"must be within {lo:g}..{hi:g}, not {_show(value)}")
    return out


_NUMBER = re.compile(r"[+-]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][+-]?\d+)?")


def parse_number(text: str) -> float | int | str:
    """Command-line text as the number it spells (``200``, ``0.5``, ``1e3``); anything else (``1_0``,
    ``" 5 "``, ``nan``) is returned as it is, for :meth:`NetFaults.set` to refuse with the field named."""
    if _NUMBER.fullmatch(text):
        digits = text.lstrip("+-")
        return int(text) if digits.isdigit() and len(digits) < 20 else float(text)  # (huge: inf, refused)
    return text


def on_param(params: Mapping[str, Any], error: Callable[[str, str], Exception] = NetFaultError) -> bool:
    """The switch ``params["on"]`` (default on): a bool, or on/off, true/false, 1/0 in any case.
    Anything else raises ``error("on", reason)`` (the world's faults share this rule)."""
    value = params.get("on", True)
    if isinstance(value, bool):
        return value
    if isinstance(value, str) and value.lower() in ("on", "off", "true", "false", "1", "0"):
        return value.lower() in ("on", "true", "1")
    raise error("on", f"must be on/off (true/false), not {value!r}")


_PARAMS = {
    "latency": ("ms", "jitter"), "bandwidth": ("rate",), "slicer": ("size", "gap"),
    "reset": ("timeout",), "silent": ("timeout",), "drop": ("p",), "reorder": ("p",), "garble": ("p",),
}


class NetFaults:
    """The network faults of one gripper (or one proxy); change them from any front end with :meth:`set`.

    Transports register a listener (:attr:`listeners`) to hear ``"reset"`` (reset switched on),
    ``"silent"`` (silent switched on) and ``"interrupt"`` (the gripper closes its connections now).
    """

    def __init__(self, seed: int = 0) -> None:
        self.s = _Settings()
        self.rng = random.Random(seed)
        self.active = False
        """Any fault on: the transports' fast path is ``if not faults.active``."""
        self.listeners: list[Callable[[str], None]] = []
        self.counts = {"dropped": 0, "reordered": 0, "garbled": 0, "reset": 0, "silenced": 0, "overflow": 0}
        """Datagrams dropped/reordered, bytes garbled, connections reset, bytes swallowed while silent,
        writes dropped because too much was held back (:data:`MAX_PENDING`)."""

    # -- switching -------------------------------------------------------------------------
    def set(self, kind: str, params: Mapping[str, Any] | None = None) -> str:
        """Switch ``kind`` on (``on`` true, default) with its parameters, or off; returns what was done.

        Parameters: latency ``ms``, ``jitter`` (ms); bandwidth ``rate`` (bytes/s); slicer ``size``
        (bytes), ``gap`` (ms); reset ``timeout`` (s); silent ``timeout`` (s, 0: never closed);
        drop/reorder/garble ``p`` (0..1); any kind ``seed`` (restarts the random sequence).
        Raises :class:`NetFaultError`.
        """
        p: Mapping[str, Any] = params or {}
        if kind not in KINDS:
            raise NetFaultError("kind", f"must be one of {', '.join(KINDS)}, not {kind!r}")
        unknown = set(p) - {*_PARAMS[kind], "on", "seed", "kind"}
        if unknown:
            raise NetFaultError(sorted(unknown)[0], f"not a parameter of {kind} ({', '.join(_PARAMS[kind])})")
        on = on_param(p)
        seed = int(_num(p, "seed", 0, 0, 2**63)) if "seed" in p else None
        s = replace(self.s)  # all parameters checked before any is applied: a refusal changes nothing
        text = self._switch(kind, on, p, s)
        self.s = s
        if seed is not None:
            self.rng.seed(seed)
        # reset is on at any timeout, 0 included ("now and at every connect"): None is its off
        self.active = s.reset is not None or any(
            getattr(s, f.name) not in (0, 0.0, None, False) for f in fields(s) if f.name != "reset")
        if on and kind in ("reset", "silent"):
            self._tell(kind)
        return text

    def _switch(self, kind: str, on: bool, p: Mapping[str, Any], s: _Settings) -> str:
        if kind == "latency":
            s.latency = _num(p, "ms", 100, 0, 600_000) / 1000 if on else 0.0
            s.jitter = min(_num(p, "jitter", 0, 0, 600_000) / 1000, s.latency) if on else 0.0
            return f"latency {s.latency * 1000:g} ms ± {s.jitter * 1000:g} ms" if on else "latency off"
        if kind == "bandwidth":
            s.rate = _num(p, "rate", 1000, 1, 1e12) if on else 0.0
            return f"bandwidth {s.rate:g} bytes/s" if on else "bandwidth off"
        if kind == "slicer":
            s.slice_size = int(_num(p, "size", 1, 1, 65536)) if on else 0
            s.slice_delay = _num(p, "gap", 0, 0, 60_000) / 1000 if on else 0.0
            return (f"replies sliced into {s.slice_size}-byte segments {s.slice_delay * 1000:g} ms apart"
                    if on else "slicer off")
        if kind == "reset":
            s.reset = _num(p, "timeout", 0, 0, 86_400) if on else None
            return f"TCP connections reset {s.reset:g} s after they open" if on else "reset off"
        if kind == "silent":
            s.silent = on
            s.close_after = _num(p, "timeout", 0, 0, 86_400) if on else 0.0
            if on and s.close_after:
                return f"gripper silent, connections closed after {s.close_after:g} s"
            return "gripper silent (connections stay open)" if on else "gripper talks again"
        prob = _num(p, "p", 1.0 if kind != "garble" else 0.01, 0, 1) if on else 0.0
        setattr(s, kind, prob)
        what = {"drop": "datagrams dropped", "reorder": "reply datagrams reordered", "garble": "bytes garbled"}[kind]
        return f"{what} with probability {prob:g}" if on else f"{kind} off"

    def clear(self) -> str:
        """Every network fault off."""
        self.s = _Settings()
        self.active = False
        return "network faults off"

    def interrupt(self) -> None:
        """The gripper closes every client connection now (TCP: FIN; see :mod:`pywsg.testing.world`)."""
        self._tell("interrupt")

    def _tell(self, what: str) -> None:
        for fn in list(self.listeners):
            fn(what)

    def state(self) -> dict[str, Any]:
        """The faults that are on, with their parameters (JSON values; ``wsg world state``)."""
        s = self.s
        out: dict[str, Any] = {}
        if s.latency:
            out["latency"] = {"ms": s.latency * 1000, "jitter": s.jitter * 1000}
        if s.rate:
            out["bandwidth"] = {"rate": s.rate}
        if s.slice_size:
            out["slicer"] = {"size": s.slice_size, "gap": s.slice_delay * 1000}
        if s.reset is not None:
            out["reset"] = {"timeout": s.reset}
        if s.silent:
            out["silent"] = {"timeout": s.close_after}
        for kind in ("drop", "reorder", "garble"):
            if getattr(s, kind):
                out[kind] = {"p": getattr(s, kind)}
        return out

    # -- questions the transports ask --------------------------------------------------------
    @property
    def silent(self) -> bool:
        return self.active and self.s.silent

    def swallow(self, data: bytes) -> bool:
        """True when incoming ``data`` must not reach the gripper (silent)."""
        if self.active and self.s.silent:
            self.counts["silenced"] += len(data)
            return True
        return False

    def lose(self) -> bool:
        """True when this datagram is lost (drop)."""
        s = self.s
        if self.active and s.drop and self.rng.random() < s.drop:
            self.counts["dropped"] += 1
            return True
        return False

    def garble_bytes(self, data: bytes) -> bytes:
        """``data`` with each byte XORed with a random non-zero value with probability ``p``."""
        s = self.s
        if not (self.active and s.garble):
            return data
        rng = self.rng
        out = bytearray(data)
        for i in range(len(out)):
            if rng.random() < s.garble:
                out[i] ^= rng.randrange(1, 256)
                self.counts["garbled"] += 1
        return bytes(out)


Write = Callable[[bytes], object]


class Shaper:
    """Sends one connection's (or datagram client's) outgoing bytes through the faults.

    ``write(data)`` puts bytes on the wire. :meth:`send` writes at once when nothing is on and
    nothing waits; otherwise the pieces wait for their due time (latency, jitter, bandwidth,
    slicer). A byte stream (``ordered``) keeps them in **one FIFO queue** behind one timer, so
    they go out in the order they were sent whatever faults are switched on or off meanwhile
    (separate timers at equal deadlines are not kept in order by the loop's heap). Datagrams
    (``ordered=False``) each get a timer of their own: they may overtake each other with jitter,
    be dropped or held back (reorder).

    ``hold``: a byte stream that must lose nothing (``wsg proxy``: its writes are arbitrary reads,
    not whole frames) passes a callback; ``hold(True)`` is called while :data:`MAX_PENDING` bytes
    wait (stop reading the source), ``hold(False)`` once half of them are out. Without it, a write
    that would exceed :data:`MAX_PENDING` is dropped whole (the sim writes whole frames).
    """

    def __init__(self, faults: NetFaults, write: Write, ordered: bool = True,
                 hold: Callable[[bool], None] | None = None) -> None:
        self.faults = faults
        self.write = write
        self.ordered = ordered
        self.hold = hold
        self._held_source = False  # hold(True) was called
        self._free = 0.0  # loop time at which the last scheduled piece is out
        self._queue: collections.deque[tuple[float, bytes, Write]] = collections.deque()
        self._timer: asyncio.TimerHandle | None = None  # the queue head's
        self._pending: set[asyncio.TimerHandle] = set()  # datagrams' own timers
        self._held: tuple[bytes, Write] | None = None
        self._held_timer: asyncio.TimerHandle | None = None
        self._last = 0.0  # loop time of the last datagram scheduled (a held one goes after it)
        self._pending_bytes = 0

    @property
    def busy(self) -> bool:
        """Bytes wait to go out (a fault was on a moment ago): later ones must queue behind them."""
        return bool(self._queue) or bool(self._pending) or self._held is not None

    def send(self, data: bytes, write: Write | None = None) -> None:
        """Send ``data`` through the faults; ``write`` (default the shaper's) puts it on the wire, so
        a datagram goes to the address that asked whenever it is sent."""
        f = self.faults
        out = write or self.write
        if not f.active and not self._queue and not self._pending and self._held is None:  # (busy, inlined)
            out(data)
            return
        s = f.s
        if s.silent:
            f.counts["silenced"] += len(data)
            return
        if not self.ordered:
            if f.lose():
                return
            if s.reorder and self._held is None and f.rng.random() < s.reorder:
                self._hold(data, out)
                return
        if self._pending_bytes + len(data) > MAX_PENDING and self.hold is None:
            f.counts["overflow"] += 1  # whole writes only: a frame is never cut
            return
        data = f.garble_bytes(data)
        loop = asyncio.get_running_loop()
        now = loop.time()
        t = now + s.latency + (f.rng.uniform(-s.jitter, s.jitter) if s.jitter else 0.0)
        if self.ordered:
            t = max(t, self._free)
        size = s.slice_size if self.ordered and s.slice_size else len(data) or 1
        pieces = [data[i:i + size] for i in range(0, len(data), size)] or [data]
        for n, piece in enumerate(pieces):
            if n and s.slice_delay:
                t += s.slice_delay
            if s.rate:  # the link carries one piece at a time, datagrams too
                t = max(t, self._free) + len(piece) / s.rate
            self._at(loop, t, piece, out)
            if self.ordered or s.rate:
                self._free = t
        self._last = t
        if self._held is not None:
            self._release_held()
        if self.hold is not None and not self._held_source and self._pending_bytes >= MAX_PENDING:
            self._held_source = True
            self.hold(True)

    def _at(self, loop: asyncio.AbstractEventLoop, t: float, piece: bytes, write: Write) -> None:
        if self.ordered:
            q = self._queue
            if not q and t <= loop.time():
                write(piece)
                return
            q.append((t, piece, write))
            self._pending_bytes += len(piece)
            if self._timer is None:
                self._timer = loop.call_at(q[0][0], self._drain)
            return
        if t <= loop.time() and not self._pending:
            write(piece)
            return
        handle: asyncio.TimerHandle | None = None

        def fire() -> None:
            assert handle is not None
            self._pending.discard(handle)
            self._pending_bytes -= len(piece)
            write(piece)

        handle = loop.call_at(t, fire)
        self._pending.add(handle)
        self._pending_bytes += len(piece)

    def _drain(self) -> None:
        """Write the queue's pieces that are due, in order; wait for the next one."""
        self._timer = None
        loop = asyncio.get_running_loop()
        now = loop.time()
        q = self._queue
        while q and q[0][0] <= now:  # (a write may close the shaper: close() empties q)
            _, piece, write = q.popleft()
            self._pending_bytes -= len(piece)
            write(piece)
        if q and self._timer is None:
            self._timer = loop.call_at(q[0][0], self._drain)
        if self._held_source and self._pending_bytes <= MAX_PENDING // 2 and self.hold is not None:
            self._held_source = False
            self.hold(False)

    def _hold(self, data: bytes, write: Write) -> None:
        self._held = (data, write)
        self.faults.counts["reordered"] += 1
        self._held_timer = asyncio.get_running_loop().call_later(REORDER_HOLD, self._release_held)

    def _release_held(self) -> None:
        held, self._held = self._held, None
        if self._held_timer is not None:
            self._held_timer.cancel()
            self._held_timer = None
        if held is not None:
            loop = asyncio.get_running_loop()
            data, write = held
            self._at(loop, max(loop.time(), self._free, self._last + 1e-6), self.faults.garble_bytes(data), write)

    def close(self) -> None:
        """Forget what waits (the connection is gone)."""
        for h in self._pending:
            h.cancel()
        self._pending.clear()
        self._queue.clear()
        if self._timer is not None:
            self._timer.cancel()
            self._timer = None
        self._pending_bytes = 0
        if self._held_timer is not None:
            self._held_timer.cancel()
        self._held = self._held_timer = None


_BY_GRIPPER: weakref.WeakKeyDictionary[Any, NetFaults] = weakref.WeakKeyDictionary()


def net_faults(gripper: Any) -> NetFaults:
    """The :class:`NetFaults` of ``gripper`` (made on first use; the sim's transports share it)."""
    nf = _BY_GRIPPER.get(gripper)
    if nf is None:
        nf = _BY_GRIPPER[gripper] = NetFaults()
    return nf
