"""pyprofibus as the DP master on the other end of the slave's pty, configured from pywsg's own GSD.

pyprofibus (GPL-2.0+) is a test dependency only. Its serial PHY opens the pty 8E1 through pyserial
(a pty's driver clears the parity bit: no parity there). Its DPM1 state machine is polled: each
``run()`` sends at most one telegram and reads what arrived; :func:`run_until` polls it with a short
sleep between calls so the master does not spin a whole core.
"""

from __future__ import annotations

import io
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from importlib import resources
from typing import Any

import pytest

pyprofibus = pytest.importorskip("pyprofibus", reason="pyprofibus is a test dependency (pip install -e '.[test]')")

MASTER = 2


def gsd_path() -> str:
    return str(resources.files("pywsg.fieldbus") / "descriptions" / "WEIS5555.gsd")


def conf_text(path: str, *, address: int = 7, watchdog_ms: int = 3000, baud: int = 19200) -> str:
    return f"""
[PROFIBUS]
debug = 0
[PHY]
type = serial
dev = {path}
baud = {baud}
[DP]
master_class = 1
master_addr = {MASTER}
[SLAVE_0]
name = wsg
addr = {address}
gsd = {gsd_path()}
input_size = 8
output_size = 12
watchdog_ms = {watchdog_ms}
"""


@contextmanager
def dp_master(path: str, **kw: Any) -> Iterator[tuple[Any, Any]]:
    """(DPM1, slave description) built by pyprofibus from WEIS5555.gsd; the PHY closed at exit."""
    conf = pyprofibus.PbConf(io.StringIO(conf_text(path, **kw)))
    master = conf.makeDPM()
    try:
        desc = conf.slaveConfs[0].makeDpSlaveDesc()
        yield master, desc
    finally:
        master.destroy()


def start(master: Any, desc: Any) -> None:
    master.addSlave(desc)
    master.initialize()


def run_until(master: Any, desc: Any, done: Callable[[bytes | None], bool], what: str, *,
              out: bytes | Callable[[], bytes] = bytes(8), timeout: float = 10.0) -> bytes | None:
    """Run the master's cycle until ``done(last inputs)``; fail saying ``what`` was awaited."""
    deadline = time.monotonic() + timeout
    last: bytes | None = None
    while time.monotonic() < deadline:
        desc.setMasterOutData(bytearray(out() if callable(out) else out))
        master.run()
        data = desc.getMasterInData()
        if data is not None:
            last = bytes(data)
        if done(last):
            return last
        time.sleep(0.0002)
    raise AssertionError(f"timed out after {timeout} s waiting for {what} (last inputs: {last!r})")
