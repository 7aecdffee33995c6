"""The controller side of the PROFINET wire tests, run inside the controller namespace.

``python pn_controller.py IFACE SCENARIO ARGS...`` prints one JSON line with what it saw. It uses
profinet-py (a real IO controller) for DCP, records, the AR and its alarms.
"""

from __future__ import annotations

import asyncio
import json
import os
import sys
import time
from typing import Any

from profinet import IOCRSetup, ProfinetDevice, dcp
from profinet.gsdml import load_gsdml
from profinet.util import ethernet_socket, get_mac

from pywsg.fieldbus.image import CmdFlag, InputImage, OutputImage
from pywsg.fieldbus.plc import GrippingCycle
from pywsg.fieldbus.profinet.exchange import ProfinetExchange, gsdml_path
from pywsg.protocol import SystemFlag

IFACE = sys.argv[1]


def out(**kw: Any) -> None:
    print(json.dumps(kw, default=str), flush=True)


def identify(name: str) -> None:
    """DCP Identify by NameOfStation, then I&M0 over a device-access AR."""
    t0 = time.monotonic()
    dev = ProfinetDevice.discover(name, IFACE, timeout=3)
    i = dev._info
    found = {"name": i.name, "ip": i.ip, "mac": i.mac, "type": i.device_type, "roles": i.device_roles,
             "vendor_id": i.vendor_high << 8 | i.vendor_low, "device_id": i.device_high << 8 | i.device_low,
             "dcp_s": round(time.monotonic() - t0, 2)}
    with dev:
        m = dev.read_im0()
    out(**found, im0={"vendor_id": m.vendor_id_high << 8 | m.vendor_id_low, "order_id": m.order_id.decode().strip(),
                      "serial": m.im_serial_number.decode().strip(), "hw": m.im_hardware_revision})


def setup(cycle_ms: int) -> IOCRSetup:
    """An AR from pywsg's GSDML; watchdog and data hold ≥ 200 ms, as ProfinetExchange uses (a loaded
    2-core machine stalls a Python controller's threads for tens of ms)."""
    gsdml = load_gsdml(str(gsdml_path()))
    factor = max(3, -(-200 // cycle_ms))
    return IOCRSetup(slots=gsdml.build_io_slots(), reduction_ratio=cycle_ms, watchdog_factor=factor,
                     data_hold_factor=factor)


async def _scl(name: str, cycles: int, cycle_ms: int) -> None:
    ex = await ProfinetExchange.open(f"profinet://{IFACE}/{name}?cycle_ms={cycle_ms}")
    cyc = GrippingCycle(log=lambda s: print(s, file=sys.stderr))
    t0 = time.monotonic()
    try:
        while cyc.cycles < cycles and time.monotonic() - t0 < 40:
            inp = InputImage.unpack(await ex.read_inputs())
            await ex.write_outputs(cyc.step(inp, time.monotonic()).pack())
    finally:
        await ex.close()
    out(cycles=cyc.cycles, holds=cyc.holds, errors=cyc.error_count, no_part=cyc.no_part,
        seconds=round(time.monotonic() - t0, 2))


def hold(name: str, seconds: float, cycle_ms: int = 16) -> None:
    """Hold an AR for ``seconds`` and report the inputs; 'silent': then vanish without a Release."""
    dev = ProfinetDevice.discover(name, IFACE, timeout=3)
    cyc = dev.start_cyclic(setup(cycle_ms), start_alarm_listener=False)
    print("AR up", file=sys.stderr, flush=True)
    time.sleep(seconds)
    data = cyc.get_input_data(1, 1)
    if len(sys.argv) > 5 and sys.argv[5] == "silent":
        out(inputs=data.hex() if data else None, stats=str(cyc.stats))
        os._exit(0)   # no Release, no stop frames: the device's watchdog must notice
    stats, state = cyc.stats, cyc.state.value
    cyc.stop()
    dev.close()
    out(inputs=data.hex() if data else None, received=stats.frames_received, missed=stats.frames_missed,
        state=state)


def diag(name: str) -> None:
    """FASTSTOP raised and acknowledged over the AR: the diagnosis alarms the controller receives."""
    got: list[dict[str, Any]] = []
    dev = ProfinetDevice.discover(name, IFACE, timeout=3)
    dev.on_alarm(lambda a: got.append({
        "type": a.alarm_type, "slot": a.slot_number, "subslot": a.subslot_number,
        "items": [(getattr(i, "channel_error_type", None), getattr(i, "channel_properties", 0) >> 11 & 3)
                  for i in a.items]}))
    cyc = dev.start_cyclic(setup(16))
    time.sleep(0.3)
    for out_bytes, pause in ((bytes([0x20, 0, 0, 0, 0, 0, 0, 0]), 0.6),   # FASTSTOP edge
                             (bytes(8), 0.2),                              # FASTSTOP back to 0
                             (bytes([0x10, 0, 0, 0, 0, 0, 0, 0]), 0.6)):   # STOP/ACK: acknowledge
        cyc.set_output_data(1, 1, out_bytes)
        time.sleep(pause)
    state = cyc.state.value
    cyc.stop()
    dev.close()
    out(alarms=got, state=state)


def dcp_scenario(name: str, mac: str) -> None:
    """Set name/IP (temporary and permanent), Get, Signal, Reset to factory — through profinet-py."""
    sock = ethernet_socket(IFACE, 3)
    src = get_mac(IFACE)
    res: dict[str, Any] = {}
    res["get_name"] = (dcp.get_param(sock, src, mac, "name") or b"").decode()
    res["set_name"] = dcp.set_param(sock, src, mac, "name", "renamed-wsg", permanent=True)
    res["found_renamed"] = ProfinetDevice.discover("renamed-wsg", IFACE, timeout=3)._info.mac
    res["set_ip"] = dcp.set_ip(sock, src, mac, "192.168.77.9", "255.255.255.0", "0.0.0.0", permanent=True)
    res["ip_after"] = ProfinetDevice.discover("renamed-wsg", IFACE, timeout=3)._info.ip
    res["signal"] = dcp.signal_device(sock, src, mac)
    time.sleep(0.3)   # profinet-py takes a queued answer with a wrong XID for its own (Signal's): a fresh socket
    sock.close()
    sock = ethernet_socket(IFACE, 3)
    try:   # profinet-py's default BlockQualifier 0002h is mode 1, "reset application data" (Wireshark agrees)
        res["reset_mode1"] = dcp.reset_to_factory(sock, src, mac)
    except dcp.DCPError as exc:
        res["reset_mode1"] = str(exc)
    res["name_after_mode1"] = (dcp.get_param(sock, src, mac, "name") or b"").decode()
    time.sleep(0.3)
    sock.close()
    sock = ethernet_socket(IFACE, 3)
    res["reset"] = dcp.reset_to_factory(sock, src, mac, mode=0x0004)   # mode 2: communication parameters
    res["name_after_reset"] = (dcp.get_param(sock, src, mac, "name") or b"").decode()
    out(**res)


def substitute(name: str) -> None:
    """Jog with JOG+/JOG- held, then send the same image with DataStatus ProviderState STOP (25h), then with
    IOPS BAD, then RUN + GOOD again: the finger width at each step (issue 31 item 1)."""
    from profinet.cyclic import IOXS_BAD, IOXS_GOOD

    dev = ProfinetDevice.discover(name, IFACE, timeout=3)
    cyc = dev.start_cyclic(setup(16))
    status: list[int | None] = [None]   # None: profinet-py's RUN; else this DataStatus on every frame
    send = cyc._send_output_frame
    cyc._send_output_frame = lambda data_status=None: send(status[0] if data_status is None else data_status)

    def width() -> float:
        data = cyc.get_input_data(1, 1)
        return InputImage.unpack(bytes(data)).width / 100 if data else float("nan")

    time.sleep(0.3)
    cyc.set_output_data(1, 1, bytes([0x08]) + bytes(7))   # HOMING, then a known position
    time.sleep(0.5)   # homing has started
    deadline = time.monotonic() + 10
    while time.monotonic() < deadline:
        time.sleep(0.2)
        data = cyc.get_input_data(1, 1)
        img = InputImage.unpack(bytes(data)) if data else None
        if img is not None and img.sysstate & SystemFlag.SF_REFERENCED and not img.sysstate & SystemFlag.SF_MOVING:
            break
    cyc.set_output_data(1, 1, bytes(8))
    time.sleep(0.1)
    jog = 0x40 if width() < 50 else 0x80   # JOG+ below mid-stroke, else JOG-: room to move either way
    image = OutputImage(CmdFlag(jog), 0, 0, 2000, 0).pack()   # 20 mm/s
    res: dict[str, Any] = {"jog": "JOG+" if jog == 0x40 else "JOG-"}
    cyc.set_output_data(1, 1, image)
    for phase in ("run", "stop", "iops_bad", "run_again"):
        if phase == "stop":
            status[0] = 0x25
        elif phase == "iops_bad":
            status[0] = None
            cyc._output_builder.set_iops(1, 1, IOXS_BAD)
        elif phase == "run_again":
            cyc._output_builder.set_iops(1, 1, IOXS_GOOD)
        time.sleep(0.3)   # the jog's start or deceleration, and a few cycles of the frames
        first = width()
        time.sleep(1.0)
        res[phase] = [first, width()]
    res["state"] = cyc.state.value
    cyc.stop()
    dev.close()
    out(**res)


def second_connect(name: str) -> None:
    """A second controller asks for the IO AR while another one holds it: the PNIO status it gets."""
    dev = ProfinetDevice.discover(name, IFACE, timeout=3)
    try:
        dev.start_cyclic(setup(16), start_alarm_listener=False)
        out(refused=False, error="")
    except Exception as exc:   # profinet-py wraps the device's negative Connect response
        out(refused=True, error=str(exc))
    finally:
        dev.close()


def main() -> None:
    scenario, args = sys.argv[2], sys.argv[3:]
    if scenario == "identify":
        identify(args[0])
    elif scenario == "scl":
        asyncio.run(_scl(args[0], int(args[1]), int(args[2])))
    elif scenario == "hold":
        hold(args[0], float(args[1]))   # argv[5] "silent": vanish without a Release
    elif scenario == "diag":
        diag(args[0])
    elif scenario == "dcp":
        dcp_scenario(args[0], args[1])
    elif scenario == "substitute":
        substitute(args[0])
    elif scenario == "second":
        second_connect(args[0])
    else:
        raise SystemExit(f"unknown scenario {scenario}")


if __name__ == "__main__":
    main()
