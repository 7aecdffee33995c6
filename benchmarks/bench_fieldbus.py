"""Modbus/TCP fieldbus figures: bus cycles/s against wsg sim vs a bare pymodbus server, edge latency.

A bus cycle is what a PLC does every scan: write the 4 output (holding) registers with FC 16, then
read the 6 input registers with FC 4. Both servers run in one background thread (own event loop,
as in ``wsg sim``); the master is pymodbus' blocking client in the main thread.

    .venv/bin/python benchmarks/bench_fieldbus.py [--cycles 3000]
"""

from __future__ import annotations

import argparse
import asyncio
import statistics
import threading
import time
from typing import Any

from pymodbus.client import ModbusTcpClient
from pymodbus.server import ModbusTcpServer
from pymodbus.simulator import DataType, SimData, SimDevice

from pywsg.fieldbus.image import CmdFlag
from pywsg.protocol import Status
from pywsg.server import SimServer


def bare_device() -> SimDevice:
    """The same four tables, no action: pymodbus alone."""
    return SimDevice(id=0, simdata=(
        [SimData(0, count=16, values=False, datatype=DataType.BITS)],
        [SimData(0, count=48, values=False, datatype=DataType.BITS)],
        [SimData(0, count=4, values=0, datatype=DataType.REGISTERS)],
        [SimData(0, count=6, values=0, datatype=DataType.REGISTERS)],
    ))


class Servers:
    def __init__(self) -> None:
        self.loop = asyncio.new_event_loop()
        self.ready = threading.Event()
        self.ports: dict[str, int] = {}
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.stop: asyncio.Event | None = None

    def _run(self) -> None:
        asyncio.set_event_loop(self.loop)
        self.loop.run_until_complete(self._main())

    async def _main(self) -> None:
        self.stop = asyncio.Event()
        bare = ModbusTcpServer(bare_device(), address=("127.0.0.1", 0))
        await bare.listen()
        self.ports["bare"] = bare.transport.sockets[0].getsockname()[1]
        async with SimServer(tcp_port=None, udp_port=None, modbus_port=0) as sim:
            self.ports["sim"] = sim.modbus_port or 0
            self.ready.set()
            await self.stop.wait()
        await bare.shutdown()

    def __enter__(self) -> Servers:
        self.thread.start()
        self.ready.wait(10)
        return self

    def __exit__(self, *exc: Any) -> None:
        assert self.stop is not None
        self.loop.call_soon_threadsafe(self.stop.set)
        self.thread.join(10)


def cycles_per_s(port: int, n: int) -> float:
    c = ModbusTcpClient("127.0.0.1", port=port)
    c.connect()
    regs = [0, 3000, 40000, 8000]
    for _ in range(200):   # warm up
        c.write_registers(0, regs, device_id=1)
        c.read_input_registers(0, count=6, device_id=1)
    t0 = time.perf_counter()
    for _ in range(n):
        c.write_registers(0, regs, device_id=1)
        rr = c.read_input_registers(0, count=6, device_id=1)
    dt = time.perf_counter() - t0
    assert not rr.isError()
    c.close()
    return n / dt


def edge_latency(port: int, n: int) -> list[float]:
    """Seconds from sending a MOVE edge until a read shows STATUS = E_CMD_PENDING."""
    c = ModbusTcpClient("127.0.0.1", port=port)
    c.connect()
    c.write_registers(0, [CmdFlag.HOMING << 8, 0, 0, 0], device_id=1)
    c.write_registers(0, [0, 0, 0, 0], device_id=1)
    while c.read_input_registers(5, count=1, device_id=1).registers[0] == Status.E_CMD_PENDING:
        time.sleep(0.01)
    out = []
    for i in range(n):
        width = 3000 if i % 2 else 6000
        c.write_registers(0, [0, width, 40000, 0], device_id=1)
        t0 = time.perf_counter()
        c.write_registers(0, [CmdFlag.MOVE << 8, width, 40000, 0], device_id=1)
        while c.read_input_registers(5, count=1, device_id=1).registers[0] != Status.E_CMD_PENDING:
            pass
        out.append(time.perf_counter() - t0)
        c.write_registers(0, [CmdFlag.STOP_ACK << 8, width, 40000, 0], device_id=1)   # stop, next round
        c.write_registers(0, [0, width, 40000, 0], device_id=1)
    c.close()
    return out


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--cycles", type=int, default=3000)
    ap.add_argument("--edges", type=int, default=300)
    args = ap.parse_args()
    with Servers() as s:
        rounds = [(cycles_per_s(s.ports["bare"], args.cycles), cycles_per_s(s.ports["sim"], args.cycles))
                  for _ in range(3)]
        lat = edge_latency(s.ports["sim"], args.edges)
    bare = max(r[0] for r in rounds)
    sim = max(r[1] for r in rounds)
    print(f"bus cycles/s (FC16 4 regs + FC4 6 regs), best of 3 x {args.cycles}:")
    print(f"  bare pymodbus server : {bare:8.0f}")
    print(f"  wsg sim (fieldbus)   : {sim:8.0f}   ratio bare/sim = {bare / sim:.2f}x")
    print("  all rounds (bare, sim): " + ", ".join(f"({b:.0f}, {m:.0f})" for b, m in rounds))
    lat_ms = sorted(x * 1000 for x in lat)
    print(f"MOVE edge -> STATUS E_CMD_PENDING read back, {len(lat)} edges: median {statistics.median(lat_ms):.3f} ms, "
          f"p99 {lat_ms[int(len(lat_ms) * 0.99) - 1]:.3f} ms, max {lat_ms[-1]:.3f} ms")


if __name__ == "__main__":
    main()
