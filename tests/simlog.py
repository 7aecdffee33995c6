"""What a test may not find in the output of a `wsg sim` it ran: a traceback of any kind.

A user runs the sim in a terminal; a traceback there is a defect even when every request was answered
(issue 33 item 4: uvloop's "Exception in callback IdleWatch._check" ~60 s after a browser left), so the
suite's sim subprocesses fail on one.
"""

from __future__ import annotations

from collections.abc import Iterable

MARKERS = ("Traceback (most recent call last)", "Exception in callback", "Task exception was never retrieved")


def tracebacks(lines: Iterable[str] | str) -> list[str]:
    """The lines of ``lines`` (a sim's stdout/stderr) that start or announce a traceback."""
    text = lines if isinstance(lines, str) else "".join(lines)
    return [line for line in text.splitlines() if any(m in line for m in MARKERS)]


def assert_no_traceback(lines: Iterable[str] | str, what: str = "wsg sim") -> None:
    text = lines if isinstance(lines, str) else "".join(lines)
    found = tracebacks(text)
    assert not found, f"{what} printed {len(found)} traceback(s):\n{text[-4000:]}"
