"""The blocking driver's command methods and lifecycle flows are generated from the asyncio ones
(issue 11: one source for the commands; issue 36: and for reconnect, error reports, ``request()``)."""

from __future__ import annotations

import inspect
import subprocess
import sys
from pathlib import Path

from pywsg import AsyncGripper, Gripper
from pywsg.client._async.commands import AsyncCommands, AsyncFinger
from pywsg.client._async.lifecycle import AsyncLifecycle
from pywsg.client._sync.generated_commands import Commands, Finger
from pywsg.client._sync.generated_lifecycle import Lifecycle

ROOT = Path(__file__).resolve().parents[2]


def test_sync_commands_are_generated_from_the_async_source() -> None:
    r = subprocess.run([sys.executable, str(ROOT / "scripts" / "unasync_client.py"), "--check"],
                       capture_output=True, text=True, timeout=60)
    assert r.returncode == 0, r.stderr


def test_both_shells_have_the_same_commands_signatures_and_docstrings() -> None:
    for sync_cls, async_cls in ((Commands, AsyncCommands), (Finger, AsyncFinger), (Lifecycle, AsyncLifecycle)):
        names = {n for n, v in vars(async_cls).items() if callable(v) and not n.startswith("__")}
        assert names == {n for n, v in vars(sync_cls).items() if callable(v) and not n.startswith("__")}
        for n in names:
            a, s = getattr(async_cls, n), getattr(sync_cls, n)
            assert inspect.iscoroutinefunction(a) or n == "finger", n
            assert not inspect.iscoroutinefunction(s), n
            assert a.__doc__ == s.__doc__ and (a.__doc__ or n.startswith("_")), n
            assert list(inspect.signature(a).parameters) == list(inspect.signature(s).parameters), n
    # the shells use them, and what differs in I/O stays in the shells
    assert issubclass(Gripper, Commands) and issubclass(AsyncGripper, AsyncCommands)
    assert issubclass(Gripper, Lifecycle) and issubclass(AsyncGripper, AsyncLifecycle)
    for n in ("state", "subscribe", "close", "connect"):
        assert n in vars(Gripper) and n in vars(AsyncGripper), n
    for n in ("request", "reconnect"):
        assert n in vars(Lifecycle) and n in vars(AsyncLifecycle), n
    # units stay in the docstrings the IDE shows
    assert "mm/s" in (Gripper.move.__doc__ or "") and "N" in (Gripper.force.__doc__ or "")
