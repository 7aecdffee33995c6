"""The system log (the web interface's "System Log" page and the manual's log entries)."""

from __future__ import annotations

from collections import deque
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from enum import Enum


class LogLevel(str, Enum):
    """A log entry's level; its value is the text (``str(LogLevel.INFO) == "info"``, as ``enum.StrEnum``
    gives on Python 3.11+, which 3.10 lacks)."""

    INFO = "info"
    WARNING = "warning"
    ERROR = "error"

    def __str__(self) -> str:
        return str(self.value)

    def __format__(self, spec: str) -> str:
        return format(str(self.value), spec)


@dataclass(frozen=True, slots=True)
class LogEntry:
    """One log line: clock time in seconds, level and text."""

    time: float
    level: LogLevel
    message: str


LogListener = Callable[[LogEntry], None]


class SystemLog:
    """Bounded in-memory log; listeners are called for every new entry."""

    def __init__(self, maxlen: int = 1000) -> None:
        self._entries: deque[LogEntry] = deque(maxlen=maxlen)
        self._listeners: list[LogListener] = []

    def add(self, time: float, level: LogLevel, message: str) -> LogEntry:
        entry = LogEntry(time, level, message)
        self._entries.append(entry)
        for fn in list(self._listeners):
            fn(entry)
        return entry

    def add_listener(self, fn: LogListener) -> None:
        self._listeners.append(fn)

    def remove_listener(self, fn: LogListener) -> None:
        if fn in self._listeners:
            self._listeners.remove(fn)

    @property
    def entries(self) -> list[LogEntry]:
        return list(self._entries)

    def __iter__(self) -> Iterator[LogEntry]:
        return iter(list(self._entries))

    def __len__(self) -> int:
        return len(self._entries)

    def messages(self) -> list[str]:
        return [e.message for e in self._entries]

    def clear(self) -> None:
        self._entries.clear()
