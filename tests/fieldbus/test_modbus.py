"""Modbus/TCP end to end on 127.0.0.1: wsg sim's server, pymodbus client and Debian's mbpoll as masters."""

from __future__ import annotations

import asyncio
import shutil
import socket
import struct
from collections.abc import AsyncIterator

import pytest
from pymodbus.client import AsyncModbusTcpClient

from pywsg.fieldbus.image import CmdFlag, InputImage, OutputImage
from pywsg.protocol import GripperState, Status, SystemFlag
from pywsg.server import SimServer

pytestmark = [pytest.mark.realtime, pytest.mark.pymodbus]  # pymodbus: also run on the oldest pin (scripts/test.sh)


@pytest.fixture
async def sim() -> AsyncIterator[SimServer]:
    async with SimServer(tcp_port=None, udp_port=None, modbus_port=0) as s:
        yield s


@pytest.fixture
async def client(sim: SimServer) -> AsyncIterator[AsyncModbusTcpClient]:
    c = AsyncModbusTcpClient("127.0.0.1", port=sim.modbus_port, timeout=2, retries=0)
    assert await c.connect()
    yield c
    c.close()


async def _inputs(c: AsyncModbusTcpClient) -> InputImage:
    rr = await c.read_input_registers(0, count=6, device_id=1)
    assert not rr.isError()
    return InputImage.from_registers(list(rr.registers))


async def _wait(c: AsyncModbusTcpClient, pred, timeout: float = 5.0) -> InputImage:  # type: ignore[no-untyped-def]
    deadline = asyncio.get_running_loop().time() + timeout
    while True:
        img = await _inputs(c)
        if pred(img):
            return img
        assert asyncio.get_running_loop().time() < deadline, img
        await asyncio.sleep(0.005)


async def test_homing_and_move_over_holding_registers(sim: SimServer, client: AsyncModbusTcpClient) -> None:
    handle = sim.grippers[0].modbus
    img = await _inputs(client)
    assert img.state == GripperState.IDLE and not img.sysstate & SystemFlag.SF_REFERENCED
    await client.write_registers(0, [CmdFlag.HOMING << 8, 0, 0, 0], device_id=1)
    img = await _inputs(client)
    assert img.status == Status.E_CMD_PENDING and img.state == GripperState.POSITIONING
    await client.write_register(0, 0, device_id=1)
    img = await _wait(client, lambda i: i.status != Status.E_CMD_PENDING)
    assert img.status == Status.E_SUCCESS and img.sysstate & SystemFlag.SF_REFERENCED
    # the manual's example value: 288 = MOVE + IF6, WIDTH 30.00 mm, SPEED 400.00 mm/s
    await client.write_registers(0, [288, 3000, 40000, 0], device_id=1)
    assert handle.controller.output_image == OutputImage(CmdFlag.MOVE, 0x20, 3000, 40000, 0)
    assert sim.grippers[0].gripper.script_if == 0x20
    img = await _wait(client, lambda i: i.status == Status.E_SUCCESS and i.state == GripperState.IDLE)
    assert img.width == 3000
    rr = await client.read_holding_registers(0, count=4, device_id=1)
    assert rr.registers == [288, 3000, 40000, 0]
    assert handle.controller.input_image().width == 3000


async def test_coils_and_discrete_inputs_mirror_the_image(sim: SimServer, client: AsyncModbusTcpClient) -> None:
    await client.write_coil(3, True, device_id=1)     # coil 3 = HOMING
    rr = await client.read_holding_registers(0, count=1, device_id=1)
    assert rr.registers == [CmdFlag.HOMING << 8]
    await client.write_coil(3, False, device_id=1)
    await _wait(client, lambda i: bool(i.sysstate & SystemFlag.SF_REFERENCED) and i.state == GripperState.IDLE)
    await client.write_coils(8, [True, False, True], device_id=1)   # IF1, IF3
    assert sim.grippers[0].gripper.script_if == 0b101
    rr = await client.read_coils(0, count=16, device_id=1)
    assert [i for i, b in enumerate(rr.bits[:16]) if b] == [8, 10]
    rr = await client.read_discrete_inputs(0, count=48, device_id=1)
    on = [i for i, b in enumerate(rr.bits[:48]) if b]
    assert 0 in on and 16 in on          # IDLE, SF_REFERENCED
    # FASTSTOP by coil 5: discrete input 28 (SF_FAST_STOP) rises
    await client.write_coil(5, True, device_id=1)
    rr = await client.read_discrete_inputs(28, count=1, device_id=1)
    assert rr.bits[0] is True


@pytest.mark.parametrize(("call", "kwargs"), [
    ("read_holding_registers", {"address": 3, "count": 2}),
    ("read_holding_registers", {"address": 4, "count": 1}),
    ("read_input_registers", {"address": 5, "count": 2}),
    ("read_input_registers", {"address": 6, "count": 1}),
    ("read_coils", {"address": 10, "count": 7}),
    ("read_coils", {"address": 16, "count": 1}),
    ("read_discrete_inputs", {"address": 47, "count": 2}),
    ("write_register", {"address": 4, "value": 1}),
    ("write_registers", {"address": 2, "values": [1, 2, 3]}),
    ("write_coil", {"address": 16, "value": True}),
])
async def test_illegal_addresses_get_exception_02(client: AsyncModbusTcpClient, call: str,
                                                  kwargs: dict[str, object]) -> None:
    rr = await getattr(client, call)(**kwargs, device_id=1)
    assert rr.isError() and rr.exception_code == 2


def _raw(port: int, pdu: bytes) -> bytes:
    mbap = struct.pack(">HHHB", 7, 0, len(pdu) + 1, 1)
    with socket.create_connection(("127.0.0.1", port), timeout=2) as s:
        s.sendall(mbap + pdu)
        return s.recv(256)[7:]


@pytest.mark.parametrize("pdu", [
    bytes([0x41, 0, 0]), bytes([0x64, 1, 2]), bytes([0x09]),
    # standard codes pymodbus would serve but the WSG map has no use for
    bytes([0x14, 7, 6, 0, 1, 0, 0, 0, 1]),   # read file record
    bytes([0x08, 0, 0, 0x12, 0x34]),         # diagnostics: return query data
    bytes([0x0B]),                           # get comm event counter
])
async def test_unsupported_function_code_gets_exception_01(sim: SimServer, pdu: bytes) -> None:
    reply = await asyncio.to_thread(_raw, sim.modbus_port or 0, pdu)
    assert reply == bytes([pdu[0] | 0x80, 0x01])


async def test_bad_quantity_gets_exception_03(sim: SimServer) -> None:
    reply = await asyncio.to_thread(_raw, sim.modbus_port or 0, bytes([0x04, 0, 0, 0, 0]))   # count 0
    assert reply == bytes([0x84, 0x03])


@pytest.mark.skipif(shutil.which("mbpoll") is None, reason="Debian mbpoll not installed")
async def test_mbpoll_reads_and_writes(sim: SimServer) -> None:
    port = str(sim.modbus_port)

    async def mbpoll(*args: str) -> str:
        proc = await asyncio.create_subprocess_exec(
            "mbpoll", "-m", "tcp", "-p", port, "-0", "-1", "-t", *args,
            stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.STDOUT)
        out, _ = await asyncio.wait_for(proc.communicate(), 10)
        assert proc.returncode == 0, out.decode()
        return out.decode()

    out = await mbpoll("3", "-r", "0", "-c", "6", "127.0.0.1")   # input registers
    assert "[0]: \t256" in out                                    # GSTATE IDLE (01h) in the high byte
    await mbpoll("4", "-r", "0", "127.0.0.1", str(CmdFlag.HOMING << 8))   # HOMING
    handle = sim.grippers[0].modbus
    assert handle.controller.output_image.cmdflags == CmdFlag.HOMING
    await asyncio.sleep(0)
    snap = sim.grippers[0].gripper.snapshot()
    assert snap.gripper_state in (GripperState.POSITIONING, GripperState.IDLE)
    for _ in range(400):
        if sim.grippers[0].gripper.snapshot().referenced:
            break
        await asyncio.sleep(0.01)
    out = await mbpoll("3", "-r", "5", "127.0.0.1")               # STATUS CODE
    assert "[5]: \t0" in out
    out = await mbpoll("1", "-r", "16", "127.0.0.1")              # discrete input 16 = SF_REFERENCED
    assert "[16]: \t1" in out
    # an illegal address makes mbpoll report the slave's exception
    proc = await asyncio.create_subprocess_exec(
        "mbpoll", "-m", "tcp", "-p", port, "-0", "-1", "-t", "4", "-r", "4", "127.0.0.1",
        stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.STDOUT)
    out_b, _ = await proc.communicate()
    assert proc.returncode != 0 and b"Illegal data address" in out_b
