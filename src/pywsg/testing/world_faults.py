"""The faults WSG users ask for in simulation, each reported the way the manuals say a real WSG does.

=====================  ==========================================================================
fault                  what the client sees (manual)
=====================  ==========================================================================
acknowledge refused    24h answers E_ACCESS_DENIED and SF_FAST_STOP stays (000 §3.2.5: the FAST
                       STOP is acknowledged "after fixing the corresponding error cause"; the
                       sim's answer while a cause persists, docs/fidelity.md)
connection interrupted the gripper closes its TCP connections; the session ended without 07h, so
                       the WSG raises FAST STOP (000 §1.4.2): a reconnecting client finds
                       SF_FAST_STOP (Appendix B, D12), 41h ERROR, motion E_ACCESS_DENIED (§3.2.4)
watchdog               no request from any client for ``timeout`` s: FAST STOP, logged as such;
                       the same flags and refusals as above
slip                   the held part slides out of the fingers; ``duration`` s later it is gone: 41h
                       PART LOST (000 §3.4.2, state 3), 42h LOST_PART + 1 (§3.4.3)
finger unplugged       a sensor finger (WSG-FMF, WSG-DSA) stops talking: 61h COMM_FAULT set,
                       CONFIG_AVAIL and COMM_OPEN cleared (§3.6.2), SF_FINGER_FAULT (Appendix B,
                       D17), 63h E_IO_ERROR. A generic finger carries no signal: 60h already
                       says "generic or no finger installed" (§3.6.1), so nothing changes
=====================  ==========================================================================

Timed faults (watchdog, slip) run on the gripper's own clock, through its timer queue: on a manual
clock they happen inside ``world.advance(dt)``, exactly on time. Each function runs on the thread
that owns the gripper.
"""

from __future__ import annotations

import weakref
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from ..device.log import LogLevel
from ..protocol import FingerType

__all__ = ["acknowledge_refused", "active", "interrupt", "slip", "unplug_finger", "watchdog"]


@dataclass
class _State:
    watchdog: float | None = None
    last_request: float = 0.0
    listener: Callable[[Any, int], None] | None = None
    token: int = 0  # a newer watchdog setting makes older timers void
    slipping: int = 0
    unplugged: set[int] = field(default_factory=set)


_STATES: weakref.WeakKeyDictionary[Any, _State] = weakref.WeakKeyDictionary()


def _state(g: Any) -> _State:
    st = _STATES.get(g)
    if st is None:
        st = _STATES[g] = _State()
    return st


def _timer(g: Any, t: float, fn: Callable[[float], None]) -> None:
    g.add_timer(t, "call", fn)
    g.notify()  # a realtime runner re-arms for the new due time


def acknowledge_refused(g: Any, on: bool) -> str:
    """While on, 24h Acknowledge FAST STOP answers E_ACCESS_DENIED and the FAST STOP stays."""
    g.ack_refused = on
    g.log.add(g.clock(), LogLevel.WARNING if on else LogLevel.INFO,
              "fault cause persists: acknowledge refused" if on else "fault cause fixed: acknowledge possible")
    g.changed()
    return f"acknowledge refused {'on' if on else 'off'}"


def interrupt(g: Any) -> str:
    """The gripper closes every client connection (TCP FIN) now."""
    from ..server.netfault import net_faults

    net_faults(g).interrupt()
    return "connections interrupted by the gripper"


def watchdog(g: Any, after: float | None) -> str:
    """FAST STOP when no request came from any client for ``after`` s (world parameter ``timeout``; None: off)."""
    st = _state(g)
    st.token += 1
    if after is None:
        st.watchdog = None
        if st.listener is not None:
            g.remove_command_listener(st.listener)
            st.listener = None
        return "watchdog off"
    st.watchdog = after
    st.last_request = g.clock()
    if st.listener is None:
        def heard(_session: Any, _command_id: int) -> None:
            st.last_request = g.clock()

        st.listener = heard
        g.add_command_listener(heard)
    _arm_watchdog(g, st, st.last_request + after)
    return f"FAST STOP after {after:g} s without a request"


def _arm_watchdog(g: Any, st: _State, due: float) -> None:
    token = st.token

    def check(t: float) -> None:
        if token != st.token or st.watchdog is None:
            return
        if t - st.last_request < st.watchdog - 1e-9:
            _arm_watchdog(g, st, st.last_request + st.watchdog)  # a request came: wait from it
            return
        if not g.fast_stopped:
            g.fast_stop(t, f"no request for {st.watchdog:g} s (watchdog)")
        st.last_request = t
        _arm_watchdog(g, st, t + st.watchdog)

    _timer(g, due, check)


def slip(g: Any, after: float) -> str:
    """The part between the fingers slides out; ``after`` s from now it is gone (held: PART LOST;
    world parameter ``duration``)."""
    part = g.obstacles.get("part")
    if part is None:
        raise ValueError("part: no part between the fingers to slip")
    st = _state(g)
    st.slipping += 1
    now = g.clock()
    g.log.add(now, LogLevel.WARNING, f"part slipping (gone in {after:g} s)")

    def gone(t: float) -> None:
        st.slipping -= 1
        if g.obstacles.get("part") is part:  # the same part: not removed or replaced meanwhile
            del g.obstacles["part"]
            g.axis.obstacles_changed(t)  # inside the device's own event loop: no nested advance
            g.changed()

    _timer(g, now + after, gone)
    return f"part slipping out, gone in {after:g} s"


def unplug_finger(g: Any, n: int, on: bool) -> str:
    """Finger ``n`` (0 or 1) unplugged (``on``) or plugged back in."""
    f = g.fingers[n]
    st = _state(g)
    (st.unplugged.add if on else st.unplugged.discard)(n)
    if f.type != FingerType.GENERIC:
        f.comm_fault = on
    g.log.add(g.clock(), LogLevel.ERROR if on else LogLevel.INFO,
              f"finger {n + 1}: {'communication lost' if on else 'connected'}")
    g.changed()
    g.notify()
    return f"finger {n + 1} {'unplugged' if on else 'plugged in'}"


def active(g: Any) -> list[str]:
    """Names of the world faults of this module that are on (for ``world_state``)."""
    st = _STATES.get(g)
    out = ["acknowledge refused"] if getattr(g, "ack_refused", False) else []
    if st is None:
        return out
    if st.watchdog is not None:
        out.append(f"watchdog {st.watchdog:g} s")
    if st.slipping:
        out.append("part slipping")
    out += [f"finger {n + 1} unplugged" for n in sorted(st.unplugged)]
    return out
