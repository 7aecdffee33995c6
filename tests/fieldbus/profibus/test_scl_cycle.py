"""The manual's SCL gripping cycle (002 App. D) over PROFIBUS DP: pyprofibus's DPM1 as the PLC's
master, the virtual WSG's DP slave on a pty, a part placed between the fingers."""

from __future__ import annotations

import asyncio
import subprocess
import sys
import time
from pathlib import Path

import pytest

from pywsg.cli.plc import run_demo
from pywsg.protocol import CATALOG, Command, Frame, SystemFlag

from ...simthread import SimThread
from .conftest import adapter

pytestmark = pytest.mark.realtime

WSG = str(Path(sys.executable).parent / "wsg")


def _fast_fingers_and_a_part(sim: SimThread) -> None:
    def setup() -> None:
        g = sim.gripper
        session = g.open_session("test", peer="test")
        payload = CATALOG[Command.SET_ACCELERATION].encode_request(acceleration=5000.0)
        assert g.handle_frame(session, Frame(int(Command.SET_ACCELERATION), payload))[0].status == 0
        g.close_session(session)
        g.faults.place_part(22.0)
    sim.call(setup)


def test_scl_cycle_holds_the_part_over_profibus(pb_sim: SimThread) -> None:
    _fast_fingers_and_a_part(pb_sim)
    ad = adapter(pb_sim)
    lines: list[str] = []
    url = f"profibus://{ad.path}?address=7&baudrate=19200&watchdog_ms=5000"
    result = asyncio.run(run_demo(url, cycles=2, timeout=40, echo=lines.append))
    assert result.completed, "\n".join(lines)
    assert (result.cycles, result.holds, result.no_part, result.errors) == (2, 2, 0, 0), "\n".join(lines)
    assert pb_sim.call(lambda: pb_sim.gripper.snapshot().statistics[0]) == 2   # the gripper counted 2 grips
    assert ad.slave.stats.data_exchanges > 10


def test_wsg_plc_demo_url_profibus(pb_sim: SimThread) -> None:
    """``wsg plc-demo --url profibus://PTY?address=7&baudrate=19200`` as a user runs it. At the end its
    master goes offline (stops polling, as a DP master leaving Operate does) and says so; the slave's
    watchdog then puts the gripper in fail-safe: FAST STOP, Wait_Prm."""
    _fast_fingers_and_a_part(pb_sim)
    ad = adapter(pb_sim)
    proc = subprocess.run([WSG, "plc-demo", "--url", f"profibus://{ad.path}?address=7&baudrate=19200&watchdog_ms=1000",
                           "--cycles", "1", "--timeout", "30"], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "done: 1 cycle, 1 part held, 0 without part, 0 error recoveries" in proc.stdout
    assert proc.stdout.strip().endswith(
        "PROFIBUS master offline: slave 7's watchdog puts the gripper in fail-safe after 1000 ms "
        "(FAST STOP, outputs zero); the next master acknowledges it with STOP/ACK")
    deadline = time.monotonic() + 10
    while pb_sim.call(lambda: ad.slave.stats.watchdog_expiries) == 0 and time.monotonic() < deadline:
        time.sleep(0.05)
    assert pb_sim.call(lambda: ad.slave.stats.watchdog_expiries) == 1
    assert pb_sim.call(lambda: pb_sim.gripper.system_flags() & SystemFlag.SF_FAST_STOP)


def test_fieldbus_gripper_grips_a_part_over_profibus(pb_sim: SimThread) -> None:
    """The blocking FieldbusGripper over ``profibus://``: homing, then GRIP holds the placed part."""
    from pywsg.fieldbus.plc import FieldbusGripper
    from pywsg.protocol import GripperState

    _fast_fingers_and_a_part(pb_sim)
    ad = adapter(pb_sim)
    with FieldbusGripper(f"profibus://{ad.path}?address=7&baudrate=19200&watchdog_ms=5000", timeout=10) as g:
        g.homing()
        assert g.grip(20.0, 100.0, 40.0).state == GripperState.HOLDING


def test_plc_demo_json_over_profibus_is_json_only(pb_factory: object) -> None:
    """pyprofibus prints its warnings (e.g. about 45450 bit/s) on stdout; ``--json`` stays one JSON
    object per line all the same (they go to the log)."""
    import json

    sim = pb_factory(tcp_port=None, udp_port=None, profibus="pty", profibus_baudrate=45450)  # type: ignore[operator]
    _fast_fingers_and_a_part(sim)
    ad = adapter(sim)
    proc = subprocess.run([WSG, "plc-demo", "--json", "--url",
                           f"profibus://{ad.path}?address=7&baudrate=45450&watchdog_ms=5000",
                           "--cycles", "1", "--timeout", "30"], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    events = [json.loads(line) for line in proc.stdout.splitlines()]   # every line is JSON
    assert events and "Warning" not in proc.stdout
