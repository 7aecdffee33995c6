"""Scenarios: a timeline of world events for one virtual gripper, read from a TOML file.

A CI job runs the same story every time: ``wsg sim --scenario FILE``, or ``SimThread(scenario=FILE)``
and the ``wsg_sim`` fixture (``@pytest.mark.wsg_sim(scenario=...)``). Each ``[[event]]`` does one
world action (:mod:`pywsg.testing.world`) at a time given in one of three ways::

    [[event]]            # absolute: seconds after the scenario started
    at = 10.0
    do = "fault"
    kind = "power"
    on = true

    [[event]]            # before each GRIP_PART (25h) request is executed ("GRIP" works too)
    before = "GRIP"
    do = "part"
    width = 22.0

    [[event]]            # 0.5 s after the gripper state (41h) becomes HOLDING, the 3rd time only
    after = "HOLDING"
    delay = 0.5
    cycle = 3
    do = "remove_part"

``cycle = N`` picks the N-th occurrence of the trigger (1-based); without it every occurrence counts.
Times are on the gripper's clock, so on a :class:`~pywsg.device.ManualClock` a scenario is exactly
repeatable. The runner is sans-IO: a host calls :meth:`ScenarioRunner.run_due` when
:meth:`ScenarioRunner.next_time` comes, and :func:`tap` reports commands and state changes (the
device's command and state listeners).
"""

from __future__ import annotations

import heapq
import math
import re
import sys
from collections import deque
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..protocol import CATALOG, GripperState
from .world import ACTIONS, WorldError, apply, check_parameters

if sys.version_info >= (3, 11):
    import tomllib
else:  # Python 3.10: the same parser, from PyPI
    import tomli as tomllib

__all__ = ["Event", "Scenario", "ScenarioError", "ScenarioRunner", "drive_realtime", "tap"]

_ALIASES = {"GRIP": "GRIP_PART", "RELEASE": "RELEASE_PART", "MOVE": "PREPOSITION", "HOME": "HOMING"}
_NAMES = {spec.name: cid for cid, spec in CATALOG.items()}
_TRIGGER_KEYS = {"at", "before", "after", "delay", "cycle", "do", "note"}


class ScenarioError(ValueError):
    """A scenario file that cannot be run; the message names the event and the key."""


def _command_id(text: str, where: str) -> int:
    name = text.strip().upper()
    name = _ALIASES.get(name, name)
    if name in _NAMES:
        return _NAMES[name]
    hexed = name[:-1] if name.endswith("H") else name[2:] if name.startswith("0X") else None
    if hexed is not None:
        try:
            cid = int(hexed, 16)
        except ValueError:
            pass
        else:
            if cid in CATALOG:
                return cid
    raise ScenarioError(f"{where}: before: unknown command {_short(repr(text))} "
                        "(a name like GRIP_PART or an ID like 25h)")


@dataclass(frozen=True)
class Event:
    """One scenario line. Exactly one of ``at`` (s), ``before`` (command ID), ``after`` (state)."""

    do: str
    params: Mapping[str, Any]
    at: float | None = None
    before: int | None = None
    after: GripperState | None = None
    delay: float = 0.0
    cycle: int | None = None
    note: str = ""

    def describe(self) -> str:
        if self.at is not None:
            when = f"at t={self.at:g} s"
        elif self.before is not None:
            when = f"before {CATALOG[self.before].name}"
        else:
            assert self.after is not None
            when = f"{self.delay:g} s after {self.after.name}" if self.delay else f"on {self.after.name}"
        if self.cycle is not None:
            when += f" (occurrence {self.cycle})"
        return f"{self.do} {when}"


@dataclass(frozen=True)
class Scenario:
    """A parsed scenario file."""

    events: tuple[Event, ...]
    source: str = "<scenario>"

    @classmethod
    def load(cls, path: str | Path) -> Scenario:
        """Read a TOML scenario file; raises ScenarioError (with the file name) when it is wrong."""
        try:
            with open(path, "rb") as f:
                data = tomllib.load(f)
        except OSError as exc:
            raise ScenarioError(f"{path}: {exc.strerror or exc}") from None
        except UnicodeDecodeError as exc:
            raise ScenarioError(f"{path}: not UTF-8 text (byte {exc.start}): a scenario is a TOML file") from None
        except ValueError as exc:  # TOMLDecodeError, or an integer beyond Python's 4,300-digit limit
            raise ScenarioError(f"{path}: not valid TOML: {_short(str(exc), 200)}") from None
        except RecursionError:
            raise ScenarioError(f"{path}: not valid TOML: nested too deeply") from None
        try:
            return cls.parse(data, str(path))
        except _UnknownParameter as exc:
            line = _line_of(Path(path).read_text(encoding="utf-8"), exc.event, exc.key)
            at = f"{path}:{line}" if line else str(path)
            raise ScenarioError(f"{at}: event {exc.event + 1}: {exc.reason}") from None

    @classmethod
    def parse(cls, data: Mapping[str, Any], source: str = "<scenario>") -> Scenario:
        raw = data.get("event", [])
        if not isinstance(raw, list) or not all(isinstance(e, dict) for e in raw):
            raise ScenarioError(f"{source}: events are [[event]] tables")
        unknown = set(data) - {"event", "description"}
        if unknown:
            raise ScenarioError(f"{source}: unknown top-level key(s): {', '.join(sorted(unknown))}")
        return cls(tuple(_event(e, f"{source}: event {i + 1}", i) for i, e in enumerate(raw)), source)


class _UnknownParameter(ScenarioError):
    """An event names a key its action does not take; :meth:`Scenario.load` adds the file's line."""

    def __init__(self, where: str, event: int, key: str, reason: str) -> None:
        super().__init__(f"{where}: {reason}")
        self.event, self.key, self.reason = event, key, reason


def _line_of(text: str, event: int, key: str) -> int | None:
    """The 1-based line of ``key = ...`` in the ``event``-th (0-based) ``[[event]]`` table, if written so."""
    seen = -1
    key_line = re.compile(rf"^\s*(?:{re.escape(key)}|\"{re.escape(key)}\"|'{re.escape(key)}')\s*=")
    for n, line in enumerate(text.splitlines(), 1):
        if re.match(r"^\s*\[\[\s*event\s*\]\]", line):
            seen += 1
        elif seen == event and key_line.match(line):
            return n
        elif seen > event:
            break
    return None


def _short(text: str, limit: int = 40) -> str:
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _show(value: Any) -> str:
    """``repr`` cut short; a huge integer (its repr may even raise) is named, not printed."""
    if isinstance(value, int) and not isinstance(value, bool) and value.bit_length() > 64:
        return "a huge integer"
    if isinstance(value, list | dict):
        return "a list" if isinstance(value, list) else "a table"
    return _short(repr(value))


def _finite(v: Any) -> bool:
    """A TOML number a float can hold (a 400-digit integer cannot)."""
    if isinstance(v, bool) or not isinstance(v, int | float):
        return False
    try:
        return math.isfinite(float(v))
    except OverflowError:
        return False


def _event(e: Mapping[str, Any], where: str, index: int = 0) -> Event:
    do = e.get("do")
    if not isinstance(do, str) or do not in ACTIONS:
        raise ScenarioError(f"{where}: do: must be one of {', '.join(ACTIONS)}, not {_show(do)}")
    triggers = [k for k in ("at", "before", "after") if k in e]
    if len(triggers) != 1:
        raise ScenarioError(f"{where}: give exactly one of at / before / after")
    params = {k: v for k, v in e.items() if k not in _TRIGGER_KEYS}
    try:  # a typo (``widht = 20``) is an error now, not a part placed without its width when the event fires
        check_parameters(do, params)
    except WorldError as exc:
        reason = f"{exc.field}: {exc.reason}; an event's own keys are {', '.join(sorted(_TRIGGER_KEYS))}"
        raise _UnknownParameter(where, index, exc.field, reason) from None
    for k, v in params.items():  # checked now, so a bad value cannot stop the story when its event fires
        if isinstance(v, int | float) and not isinstance(v, bool) and not _finite(v):
            raise ScenarioError(f"{where}: {k}: must be a finite number, not {_show(v)}")
        if not isinstance(v, str | int | float | bool):
            raise ScenarioError(f"{where}: {k}: must be a number, string or boolean, not {_show(v)}")

    def num(key: str, default: float | None) -> float | None:
        v = e.get(key, default)
        if v is None:
            return None
        if not _finite(v) or v < 0:
            raise ScenarioError(f"{where}: {key}: must be a non-negative number of seconds, not {_show(v)}")
        return float(v)

    cycle = e.get("cycle")
    if cycle is not None and (isinstance(cycle, bool) or not isinstance(cycle, int) or not 1 <= cycle < 2**31):
        raise ScenarioError(f"{where}: cycle: must be a whole number from 1, not {_show(cycle)}")
    before = after = None
    for key in ("before", "after", "note"):
        if key in e and not isinstance(e[key], str):
            raise ScenarioError(f"{where}: {key}: must be a string, not {_show(e[key])}")
    if "before" in e:
        before = _command_id(e["before"], where)
    if "after" in e:
        try:
            after = GripperState[e["after"].upper()]
        except KeyError:
            names = ", ".join(s.name for s in GripperState)
            raise ScenarioError(f"{where}: after: must be a gripper state ({names}), not {_show(e['after'])}") from None
    if "at" in e and (cycle is not None or "delay" in e):
        raise ScenarioError(f"{where}: at: cycle and delay only go with before/after")
    return Event(do=do, params=params, at=num("at", None), before=before, after=after,
                 delay=num("delay", 0.0) or 0.0, cycle=cycle, note=e.get("note", ""))


LOG_LIMIT = 1000
"""How many of the latest actions :attr:`ScenarioRunner.log` keeps: a ``before`` event fires on every matching
request, so a client decides how often; an unbounded log grew 32 -> 58 MB over 60k requests."""

REPORT_BURST = 100
REPORT_RATE = 20.0
"""``on_action`` hears at most REPORT_BURST actions at once and REPORT_RATE a second (gripper clock) after that;
the rest are counted and told in one line when reporting resumes (``wsg sim`` printed 17.6 MB for 60k
requests before)."""


@dataclass
class ScenarioRunner:
    """Runs a :class:`Scenario` against one gripper, starting at ``start`` (s on its clock).

    ``log`` keeps the latest :data:`LOG_LIMIT` ``(time, what happened)``; ``on_action`` is told the same
    (``wsg sim`` prints it), at a bounded rate (:data:`REPORT_RATE`), with a count of what it was not told.
    World actions refused by the device (say a width beyond the stroke) are logged, not raised:
    the story goes on.
    """

    scenario: Scenario
    gripper: Any
    start: float = 0.0
    on_action: Callable[[float, str], None] | None = None
    on_queue: Callable[[], None] | None = None
    """Called when a timed action was queued (a realtime host re-arms its timer)."""
    log: deque[tuple[float, str]] = field(default_factory=lambda: deque(maxlen=LOG_LIMIT))
    actions: int = 0
    """How many actions were carried out in all (the log keeps only the latest)."""
    _tokens: float = REPORT_BURST
    _refilled: float | None = None
    _unreported: int = 0
    _pending: list[tuple[float, int, Event]] = field(default_factory=list)
    _counts: dict[int, int] = field(default_factory=dict)
    _state: GripperState | None = None
    _seq: int = 0
    _before: dict[int, list[Event]] = field(default_factory=dict)
    _after: dict[GripperState, list[Event]] = field(default_factory=dict)

    def __post_init__(self) -> None:
        # a heap and per-trigger indexes: loading and serving stay linear in the number of events
        for ev in self.scenario.events:
            if ev.at is not None:
                self._seq += 1
                self._pending.append((self.start + ev.at, self._seq, ev))
            elif ev.before is not None:
                self._before.setdefault(ev.before, []).append(ev)
            elif ev.after is not None:
                self._after.setdefault(ev.after, []).append(ev)
        heapq.heapify(self._pending)
        self._state = self.gripper.snapshot().gripper_state

    def _queue(self, t: float, ev: Event) -> None:
        self._seq += 1
        heapq.heappush(self._pending, (t, self._seq, ev))
        if self.on_queue is not None:
            self.on_queue()

    def next_time(self) -> float | None:
        """When the next timed action falls due (s on the gripper's clock), or None."""
        return self._pending[0][0] if self._pending else None

    def run_due(self, now: float) -> None:
        """Carry out every timed action due at ``now``."""
        while self._pending and self._pending[0][0] <= now:
            _, _, ev = heapq.heappop(self._pending)
            self._do(ev, now)

    def _fires(self, ev: Event) -> bool:
        n = self._counts[id(ev)] = self._counts.get(id(ev), 0) + 1
        return ev.cycle is None or ev.cycle == n

    def before_command(self, command_id: int, now: float) -> None:
        """A request with ``command_id`` is about to be executed."""
        self.run_due(now)
        for ev in self._before.get(command_id, ()):
            if self._fires(ev):
                self._do(ev, now)

    def observe(self, now: float) -> None:
        """Look at the gripper state; a change starts the ``after`` events for the new state (for
        hosts, after a timed action; :func:`tap` reports every change through the device)."""
        self.state_changed(self.gripper.snapshot().gripper_state, now)

    def state_changed(self, state: GripperState, now: float) -> None:
        """The gripper state became ``state``: start the ``after`` events for it (once per change)."""
        if state == self._state:
            return
        self._state = state
        for ev in self._after.get(state, ()):
            if self._fires(ev):
                if ev.delay:
                    self._queue(now + ev.delay, ev)
                else:
                    self._do(ev, now)

    def _do(self, ev: Event, now: float) -> None:
        try:
            text = apply(self.gripper, ev.do, ev.params)
        except WorldError as exc:
            text = f"{ev.do} refused: {exc}"
        line = f"{text} ({ev.describe()}{', ' + ev.note if ev.note else ''})"
        self.actions += 1
        self.log.append((now - self.start, line))
        if self.on_action is not None and self._may_report(now):
            if self._unreported:
                self.on_action(now - self.start, f"... {self._unreported} more scenario action(s) not shown")
                self._unreported = 0
            self.on_action(now - self.start, line)

    def _may_report(self, now: float) -> bool:
        """A token bucket on the gripper's clock: REPORT_BURST at once, REPORT_RATE a second after that."""
        if self._refilled is not None:
            self._tokens = min(REPORT_BURST, self._tokens + (now - self._refilled) * REPORT_RATE)
        self._refilled = now
        if self._tokens >= 1.0:
            self._tokens -= 1.0
            return True
        self._unreported += 1
        return False


def tap(gripper: Any, runner: ScenarioRunner) -> Callable[[], None]:
    """Let ``runner`` hear ``gripper``'s requests and state changes; returns a function that undoes it.

    Uses the device's listener API (docs/device.md): a command listener runs the ``before`` events
    before each request is executed (from any interface), a state listener the ``after`` events on
    each change of the gripper state (41h). Timed events are the host's to serve
    (:func:`drive_realtime`, or the manual clock's ``World.advance``).
    """
    clock = gripper.clock

    def on_command(_session: Any, command_id: int) -> None:
        runner.before_command(command_id, clock())

    def on_state(_old: GripperState, new: GripperState) -> None:
        runner.state_changed(new, clock())

    gripper.add_command_listener(on_command)
    gripper.add_state_listener(on_state)

    def undo() -> None:
        gripper.remove_command_listener(on_command)
        gripper.remove_state_listener(on_state)

    return undo


async def drive_realtime(runner: ScenarioRunner, clock: Callable[[], float]) -> None:
    """Serve ``runner``'s timed actions on the running loop at their times (real clock); cancel to stop."""
    import asyncio

    from ..device.clock import real_seconds

    wake = asyncio.Event()
    runner.on_queue = wake.set
    try:
        while True:
            due = runner.next_time()
            wake.clear()
            if due is None:
                await wake.wait()
                continue
            delay = real_seconds(clock, due - clock())  # a scaled clock runs faster than real time
            if delay > 0:
                try:
                    await asyncio.wait_for(wake.wait(), delay)
                    continue  # something earlier was queued
                except asyncio.TimeoutError:  # before Python 3.11 not the builtin TimeoutError (same class since)
                    pass
            now = clock()
            runner.run_due(now)
            runner.observe(now)
    finally:
        runner.on_queue = None
