"""PLC side over real Modbus/TCP: FieldbusGripper, and `wsg plc-demo` against wsg sim (real process)."""

from __future__ import annotations

import asyncio
import sys
from collections.abc import AsyncIterator
from pathlib import Path

import pytest

from pywsg.cli.plc import DemoResult, run_demo
from pywsg.fieldbus.plc import AsyncFieldbusGripper, FieldbusError, FieldbusGripper
from pywsg.protocol import CATALOG, Command, Frame, GripperState, Status, SystemFlag
from pywsg.server import SimServer

pytestmark = [pytest.mark.realtime, pytest.mark.pymodbus]  # pymodbus: also run on the oldest pin (scripts/test.sh)

WSG = str(Path(sys.executable).parent / "wsg")


@pytest.fixture
async def sim() -> AsyncIterator[SimServer]:
    async with SimServer(tcp_port=None, udp_port=None, modbus_port=0) as s:
        # Fast fingers (30h Set Acceleration, 5000 mm/s²) keep the 3-cycle demo within the test budget.
        g = s.grippers[0].gripper
        session = g.open_session("test", peer="test")
        payload = CATALOG[Command.SET_ACCELERATION].encode_request(acceleration=5000.0)
        assert g.handle_frame(session, Frame(int(Command.SET_ACCELERATION), payload))[0].status == 0
        g.close_session(session)
        yield s


async def _plc_demo(port: int, *args: str) -> tuple[int, str]:
    proc = await asyncio.create_subprocess_exec(
        WSG, "plc-demo", "--url", f"modbus-tcp://127.0.0.1:{port}", "--timeout", "25", *args,
        stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.STDOUT)
    out, _ = await asyncio.wait_for(proc.communicate(), 40)
    return proc.returncode or 0, out.decode()


async def test_plc_demo_three_cycles_with_a_part(sim: SimServer) -> None:
    sim.grippers[0].gripper.faults.place_part(22.0)
    rc, out = await _plc_demo(sim.modbus_port or 0, "--cycles", "3")
    assert rc == 0, out
    assert "done: 3 cycles, 3 parts held, 0 without part, 0 error recoveries" in out
    for step in ("step  0 ->  1", "step  6 ->  7", "step  7 ->  8", "step 10 -> 11"):
        assert step in out
    snap = sim.grippers[0].gripper.snapshot()
    assert snap.statistics[0] == 3            # three grips counted by the gripper itself
    assert sim.grippers[0].modbus.controller.output_image.cmdflags == 0   # no flag left raised


async def test_plc_demo_recovers_from_an_injected_fast_stop(sim: SimServer) -> None:
    sim.grippers[0].gripper.faults.place_part(22.0)
    rc, out = await _plc_demo(sim.modbus_port or 0, "--cycles", "3", "--fast-stop-cycle", "2")
    assert rc == 0, out
    assert "injected fault: FASTSTOP" in out
    assert "-> -1" in out and "step -1 ->  0" in out          # error state, STOP/ACK, re-homing
    assert "done: 3 cycles" in out and ", 1 error recovery" in out
    snap = sim.grippers[0].gripper.snapshot()
    assert not snap.fast_stop and snap.referenced


async def _fast_stop_while_gripping(sim: SimServer, recover: bool, timeout: float) -> tuple[DemoResult, list[str]]:
    """run_demo with a FAST STOP (23h, another interface) raised the moment the cycle enters step 7
    (before it can see HOLDING and start its hold timer): deterministic, whatever the scan timing."""
    g = sim.grippers[0].gripper
    g.faults.place_part(22.0)
    lines: list[str] = []

    def echo(text: str) -> None:
        lines.append(text)
        if "step  6 ->  7" in text and not g.snapshot().fast_stop and not any("->  7" in t for t in lines[:-1]):
            g.raise_fast_stop("test: 23h while gripping")

    result = await run_demo(f"modbus-tcp://127.0.0.1:{sim.modbus_port}", 1, echo=echo, timeout=timeout,
                            recover_fast_stop=recover)
    return result, lines


async def test_demo_runs_the_listing_exactly_and_says_why_it_is_stuck(sim: SimServer) -> None:
    """002 App. D + §4.6 (default, no --recover-fast-stop): after a FAST STOP during the grip the
    listing waits in step 7 for ever; the demo ends at its timeout with a one-line reason."""
    result, lines = await _fast_stop_while_gripping(sim, recover=False, timeout=4)
    assert not result.completed and result.errors == 0
    stuck = [line for line in lines if line.startswith("stuck in step 7")]
    assert len(stuck) == 1 and "--recover-fast-stop" in stuck[0], lines[-5:]
    assert "timed out after 4 s" in lines[-1]


async def test_demo_with_recover_fast_stop_acknowledges_and_finishes(sim: SimServer) -> None:
    """--recover-fast-stop: the same FAST STOP goes to the listing's error step −1 (STOP/ACK), homing, grip."""
    result, lines = await _fast_stop_while_gripping(sim, recover=True, timeout=20)
    assert result.completed and result.errors >= 1 and result.holds >= 1, lines[-8:]
    assert any("step  7 -> -1" in line for line in lines)
    assert not any(line.startswith("stuck") for line in lines)


async def test_demo_without_part_releases_at_once(sim: SimServer) -> None:
    lines: list[str] = []
    result = await run_demo(f"modbus-tcp://127.0.0.1:{sim.modbus_port}", 1, echo=lines.append, timeout=20)
    assert result.completed and result.no_part == 1 and result.holds == 0
    assert any("[NO_PART, E_CMD_FAILED]" in line for line in lines)


def test_plc_demo_without_a_gripper_says_so() -> None:
    import subprocess

    out = subprocess.run([WSG, "plc-demo", "--url", "modbus-tcp://127.0.0.1:1", "--timeout", "2"],
                         capture_output=True, text=True, timeout=30)
    assert out.returncode != 0 and "cannot connect" in out.stderr


async def test_async_fieldbus_gripper(sim: SimServer) -> None:
    g = await AsyncFieldbusGripper.open("127.0.0.1", sim.modbus_port or 0)
    async with g:
        img = await g.homing()
        assert img.status == Status.E_SUCCESS and img.sysstate & SystemFlag.SF_REFERENCED
        img = await g.move(30.0, 400.0)
        assert img.width_mm == pytest.approx(30.0) and img.state == GripperState.IDLE
        await g.set_user_flags(0x81)
        assert sim.grippers[0].gripper.script_if == 0x81
        img = await g.jog(+1, speed=50.0, force=0)
        await asyncio.sleep(0.2)
        img = await g.read()
        assert img.state == GripperState.RELEASING and img.width_mm > 31.0
        img = await g.jog(0)
        await asyncio.sleep(0.1)
        assert not (await g.read()).sysstate & SystemFlag.SF_MOVING


async def test_a_move_to_where_the_fingers_are_returns_at_once(sim: SimServer) -> None:
    """002 §4.1 MOVE to the current width: the gripper is done before the first read shows it running;
    the command returns its result instead of waiting 10 s for a start it cannot see."""
    g = await AsyncFieldbusGripper.open("127.0.0.1", sim.modbus_port or 0)
    async with g:
        await g.homing()
        await g.move(30.0, 400.0)
        loop = asyncio.get_running_loop()
        t0 = loop.time()
        img = await g.move(30.0, 400.0, timeout=5.0)
        assert loop.time() - t0 < 2.0
        assert img.status == Status.E_SUCCESS and img.width_mm == pytest.approx(30.0)


async def test_homing_when_already_at_the_end_stop_returns(sim: SimServer) -> None:
    """002 §4.4 HOMING twice: the second homing starts at the end stop and still runs (000 §3.2.1), so
    the command sees it start and end instead of timing out after 10 s."""
    g = await AsyncFieldbusGripper.open("127.0.0.1", sim.modbus_port or 0)
    async with g:
        await g.homing()
        loop = asyncio.get_running_loop()
        t0 = loop.time()
        img = await g.homing(timeout=5.0)
        assert loop.time() - t0 < 3.0
        assert img.status == Status.E_SUCCESS and img.sysstate & SystemFlag.SF_REFERENCED
        assert img.width_mm == pytest.approx(110.0)


async def test_grip_without_part_raises_with_the_image(sim: SimServer) -> None:
    async with await AsyncFieldbusGripper.open("127.0.0.1", sim.modbus_port or 0) as g:
        await g.homing()
        await g.move(30.0, 400.0)
        with pytest.raises(FieldbusError) as exc:
            await g.grip(22.0, 400.0, 50.0)
        assert exc.value.status == Status.E_CMD_FAILED
        assert exc.value.image is not None and exc.value.image.state == GripperState.NO_PART
        assert g.outputs.cmdflags == 0            # the GRIP flag was dropped again


async def test_blocking_fieldbus_gripper(sim: SimServer) -> None:
    sim.grippers[0].gripper.faults.place_part(22.0)
    port = sim.modbus_port or 0

    def plc() -> tuple[float, GripperState, Status | int | None]:
        with FieldbusGripper("127.0.0.1", port) as g:
            g.homing()
            g.move(30.0, 400.0)
            held = g.grip(22.0, 400.0, 50.0)
            g.release(30.0, 400.0)
            with pytest.raises(FieldbusError) as exc:
                g.move(200.0, 400.0)              # beyond the stroke: FAST STOP
            g.acknowledge()
            return held.force_n(), held.state or GripperState.ERROR, exc.value.status

    force, state, status = await asyncio.to_thread(plc)
    assert state == GripperState.HOLDING and force == pytest.approx(50.0, abs=1.0)
    assert status == Status.E_RANGE_ERROR
    assert not sim.grippers[0].gripper.snapshot().fast_stop
