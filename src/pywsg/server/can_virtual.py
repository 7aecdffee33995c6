"""python-can's ``virtual`` bus, a batch at a time (issue 33 item 13).

The sim's CAN server on the ``virtual`` interface (the one tests and ``wsg sim --can`` use where there
is no ``vcan``) spent most of a flood of bad frames in python-can's per-message paths: ``send``
deep-copies each message for every other bus on the channel and puts it in that bus's
:class:`queue.Queue` (a lock and a notify per message); the ``Notifier`` thread takes them out one
``recv`` at a time (a lock per message, the acceptance filter in Python). Here the same work is
done once per batch: :func:`send_many` hands each receiver fresh ``can.Message`` objects (the copies
``send`` would make: the channel, ``is_rx``, one timestamp) under one lock per receiver, and
:class:`Reader` takes every queued message under one lock.

Both rely on python-can's ``VirtualBus`` keeping each receiver's :class:`queue.Queue` in ``channel``
and its own in ``queue`` (python-can 4.x). :func:`batchable` checks that shape; any other bus, or a
bounded receive queue (``rx_queue_size``, where ``send`` blocks or fails per message), goes through
python-can's own ``send``/``recv``.
"""

from __future__ import annotations

import functools
import queue
import threading
import time
from collections.abc import Callable, Iterable
from typing import Any


def batchable(bus: Any) -> bool:
    """Whether ``bus`` is a python-can ``VirtualBus`` of the known shape, with unbounded queues."""
    try:
        from can.interfaces.virtual import VirtualBus
    except ImportError:  # pragma: no cover - python-can without the virtual interface
        return False
    return (isinstance(bus, VirtualBus) and isinstance(getattr(bus, "queue", None), queue.Queue)
            and isinstance(getattr(bus, "channel", None), list)
            and isinstance(getattr(bus, "receive_own_messages", None), bool)
            and isinstance(getattr(bus, "preserve_timestamps", None), bool))


def send_many(bus: Any, can_id: int, chunks: Iterable[bytes]) -> bool:
    """Send ``chunks`` (≤ 8 bytes each) as standard-identifier data frames on ``can_id``, in order, to
    every other bus on ``bus``'s channel, as ``bus.send`` would one by one. False (nothing sent) when a
    receiver's queue is bounded, or ``bus.send`` was replaced on the instance (a wrapper injecting faults
    or logging): the caller then uses ``bus.send``."""
    import can

    if "send" in vars(bus):
        return False
    receivers = [q for q in bus.channel if q is not bus.queue or bus.receive_own_messages]
    if any(q.maxsize > 0 for q in receivers):
        return False
    data = list(chunks)
    if not data:
        return True
    stamp = 0.0 if bus.preserve_timestamps else time.time()  # our messages carry no timestamp
    make, channel = _maker(can.Message), bus.channel_id
    for q in receivers:
        rx = q is not bus.queue
        msgs = [make(stamp, can_id, channel, rx, d) for d in data]
        with q.mutex:  # what Queue.put does, once for the batch
            q.queue.extend(msgs)
            q.unfinished_tasks += len(msgs)
            q.not_empty.notify(len(msgs))
    return True


_FIELDS = frozenset({"timestamp", "arbitration_id", "is_extended_id", "is_remote_frame", "is_error_frame",
                     "channel", "is_fd", "is_rx", "bitrate_switch", "error_state_indicator", "data", "dlc"})


@functools.cache
def _maker(message: type) -> Callable[[float, int, Any, bool, bytes], Any]:
    """A function making a standard-identifier data frame as ``message(...)`` would: when
    ``can.Message`` has the fields it had in python-can 4.x, by setting them directly (1.5 µs instead of
    4 µs through its keyword arguments), else through its constructor."""
    if set(getattr(message, "__slots__", ())) - {"__weakref__"} != _FIELDS:
        def slow(stamp: float, can_id: int, channel: Any, rx: bool, data: bytes) -> Any:
            return message(timestamp=stamp, arbitration_id=can_id, is_extended_id=False, channel=channel,
                           data=bytearray(data), is_rx=rx)
        return slow
    new = object.__new__

    def fast(stamp: float, can_id: int, channel: Any, rx: bool, data: bytes) -> Any:
        m: Any = new(message)
        m.timestamp, m.arbitration_id, m.channel, m.is_rx = stamp, can_id, channel, rx
        m.is_extended_id = m.is_remote_frame = m.is_error_frame = m.is_fd = False
        m.bitrate_switch = m.error_state_indicator = False
        m.data = bytearray(data)
        m.dlc = len(data)
        return m
    return fast


class Reader:
    """A thread that hands ``callback`` every batch of messages queued for a virtual ``bus`` (what
    python-can's ``Notifier`` does a message at a time). No acceptance filter is applied: the caller
    checks each message's identifier anyway (``bus.recv`` would apply the bus's filters)."""

    def __init__(self, bus: Any, callback: Callable[[list[Any]], None], name: str = "can-virtual-reader") -> None:
        self._queue: queue.Queue[Any] = bus.queue
        self._callback = callback
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        q = self._queue
        while True:
            first = q.get()  # blocks until a message, or stop()'s sentinel
            with q.mutex:  # what Queue.get does, once for the rest of the batch
                msgs = [first, *q.queue]
                q.queue.clear()
                q.not_full.notify_all()
            if any(m is _STOP for m in msgs):  # stop(): what is still queued is dropped
                return
            self._callback(msgs)

    def stop(self, timeout: float = 5.0) -> None:
        """Wake the thread and wait (up to ``timeout`` s) for it to end; messages still queued are dropped."""
        self._queue.put(_STOP)
        self._thread.join(timeout)


_STOP = object()
