"""PROFINET IO benchmark: the shortest cycle the virtual WSG holds beside profinet-py's controller.

Needs root (network namespaces, raw sockets). Two namespaces joined by a veth pair: ``wsg sim
--profinet eth0`` in one, profinet-py's IO controller (an AR built from pywsg's GSDML, watchdog and data
hold factor 3 as an engineering tool sets them by default) in the other. For each cycle time, for
``--seconds`` each, the controller side records the arrival time of every input frame the device sends
(a second raw socket) and the benchmark counts:

- watchdog expiries: ARs the device ended because output frames stopped for the data hold time, and
  watchdog timeouts profinet-py's consumer saw on the input frames;
- jitter: |interval between two input frames − cycle|, p50 / p99 / max, in ms.

A cycle is held when there is no expiry and p99 jitter ≤ 25 % of the cycle. Results: docs/benchmarks.md.
``--min-interval`` lets the sim accept cycles below the GSDML's MinDeviceInterval (to find the one to
declare); ``--hogs N`` runs N busy processes (``yes``) meanwhile; the load average is printed before and after.

    sudo .venv/bin/python benchmarks/bench_profinet.py [--seconds 60] [--cycles 8,4,2,1] [--rt 20] [--hogs 2]
"""

from __future__ import annotations

import argparse
import gc
import itertools
import json
import os
import socket
import statistics
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
WSG = [sys.executable, "-c", "from pywsg.cli.main import main; main()"]


def controller(iface: str, station: str, cycle_ms: int, seconds: float) -> None:
    """Runs in the controller namespace: one AR for ``seconds``; prints one JSON line."""
    from profinet import IOCRSetup, ProfinetDevice
    from profinet.gsdml import load_gsdml

    from pywsg.fieldbus.profinet.exchange import gsdml_path

    # profinet-py's sending thread shares the GIL with its receiving thread and this loop: at Python's
    # default 5 ms switch interval the controller itself stalls for several 1-2 ms cycles
    sys.setswitchinterval(0.0002)
    # and a full (generation 2) garbage collection of profinet-py's objects stops every thread for 10-20 ms
    # every ~1,300 frames: freeze what exists, so the collections that remain are short
    gc.collect()
    gc.freeze()
    slots = load_gsdml(str(gsdml_path())).build_io_slots()
    setup = IOCRSetup(slots=slots, reduction_ratio=cycle_ms, watchdog_factor=3, data_hold_factor=3)
    dev = ProfinetDevice.discover(station, iface, timeout=3)
    cyc = dev.start_cyclic(setup, start_alarm_listener=False)
    rx = socket.socket(socket.AF_PACKET, socket.SOCK_RAW, socket.htons(0x8892))
    rx.bind((iface, 0))
    rx.settimeout(0.5)
    dev_mac = bytes.fromhex(dev.mac.replace(":", ""))
    stamps: list[float] = []
    timeouts0 = cyc.stats.frames_missed
    end = time.monotonic() + seconds
    cyc.set_output_data(1, 1, bytes(8))
    while time.monotonic() < end:
        try:
            data = rx.recv(2048)
        except TimeoutError:
            continue
        now = time.monotonic()
        if data[6:12] != dev_mac:
            continue
        off = 16 if data[12:14] == b"\x81\x00" else 12
        if data[off:off + 2] == b"\x88\x92" and 0xC000 <= int.from_bytes(data[off + 2:off + 4], "big") < 0xFC00:
            stamps.append(now)
    state = cyc.state.value
    timeouts = cyc.stats.frames_missed - timeouts0
    dev.disconnect()   # Release first: output frames stopping after it are no watchdog case
    time.sleep(0.05)
    cyc.stop()
    dev.close()
    gaps = [(b - a) * 1000 for a, b in itertools.pairwise(stamps)]
    jit = sorted(abs(g - cycle_ms) for g in gaps) or [float("nan")]
    print(json.dumps({"cycle_ms": cycle_ms, "frames": len(stamps), "state": state, "consumer_timeouts": timeouts,
                      "jitter_p50": statistics.median(jit), "jitter_p99": jit[int(0.99 * (len(jit) - 1))],
                      "jitter_max": jit[-1]}), flush=True)


def flood(port: int) -> None:
    """Runs in the device namespace: 43h Get Width requests to the sim's TCP port, back to back, answers read
    and dropped, until killed (a client as busy as the binary protocol allows)."""
    from pywsg.protocol.frame import encode_frame

    req = encode_frame(0x43, b"\x00\x00") * 16
    while True:
        try:
            with socket.create_connection(("127.0.0.1", port), timeout=5) as s:
                while True:
                    s.sendall(req)
                    s.recv(65536)
        except OSError:
            time.sleep(0.1)


def _ip(*args: str) -> None:
    subprocess.run(["ip", *args], check=True, capture_output=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seconds", type=float, default=60.0)
    ap.add_argument("--cycles", default="8,4,2,1", help="cycle times to try, ms (powers of two)")
    ap.add_argument("--min-interval", type=int, default=0, metavar="UNITS",
                    help="let the sim accept cycles down to this many 31.25 us units (default: the GSDML's)")
    ap.add_argument("--hogs", type=int, default=0, help="busy processes (yes >/dev/null) to run meanwhile")
    ap.add_argument("--sim-log", type=Path, help="write the sim's log here")
    ap.add_argument("--flood", type=int, default=0, metavar="N",
                    help="N clients flooding the sim's TCP command port meanwhile (the rest of the process busy)")
    ap.add_argument("--flood-client", nargs=1, metavar="PORT", help=argparse.SUPPRESS)
    ap.add_argument("--rt", type=int, default=0, metavar="PRIO",
                    help="run the sim and the controller under SCHED_FIFO at this priority (chrt -f PRIO); 0: normal")
    ap.add_argument("--controller", nargs=4, metavar=("IFACE", "STATION", "CYCLE_MS", "SECONDS"),
                    help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.flood_client:
        flood(int(args.flood_client[0]))
        return
    if args.controller:
        iface, station, cycle, secs = args.controller
        controller(iface, station, int(cycle), float(secs))
        return
    if os.geteuid() != 0:
        sys.exit("bench_profinet needs root (network namespaces and raw sockets)")
    tag = f"pnb{os.getpid()}"
    dev, ctl = f"{tag}-dev", f"{tag}-ctl"
    sim = None
    hogs: list[subprocess.Popen[bytes]] = []
    try:
        _ip("netns", "add", dev)
        _ip("netns", "add", ctl)
        _ip("-n", dev, "link", "add", "eth0", "type", "veth", "peer", "name", "eth0", "netns", ctl)
        _ip("-n", ctl, "addr", "add", "192.168.77.1/24", "dev", "eth0")
        for ns in (dev, ctl):
            _ip("-n", ns, "link", "set", "eth0", "up")
            _ip("-n", ns, "link", "set", "lo", "up")
        chrt = ["chrt", "-f", str(args.rt)] if args.rt else []
        wsg = WSG
        if args.min_interval:
            wsg = [sys.executable, "-c", "import pywsg.fieldbus.profinet.ar as a; "
                   f"a.MIN_DEVICE_INTERVAL = {args.min_interval}; from pywsg.cli.main import main; main()"]
        hogs = [subprocess.Popen(["yes"], stdout=subprocess.DEVNULL) for _ in range(args.hogs)]
        print(f"priority: {'SCHED_FIFO ' + str(args.rt) if args.rt else 'normal'}; CPU hogs: {args.hogs}; "
              f"TCP flood clients: {args.flood}; "
              f"{os.cpu_count()} CPUs; load average {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
        sim = subprocess.Popen(["ip", "netns", "exec", dev, *chrt, *wsg, "-v", "sim", "--no-uvloop", "--tcp-port", "0",
                                "--udp-port", "0", "--serial", "off", "--web-port", "off", "--profinet", "eth0",
                                *(["--tcp-port", "1000"] if args.flood else []),
                                "--profinet-name", "wsg-bench", "--profinet-ip", "192.168.77.2/24"],
                               stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        time.sleep(3)
        hogs += [subprocess.Popen(["ip", "netns", "exec", dev, sys.executable, __file__, "--flood-client", "1000"],
                                  stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL) for _ in range(args.flood)]
        print(f"{'cycle':>6} {'frames':>7} {'expiries':>8} {'jitter p50/p99/max ms':>24}  held")
        results = []
        for cycle in (int(c) for c in args.cycles.split(",")):
            r = subprocess.run(["ip", "netns", "exec", ctl, *chrt, sys.executable, __file__, "--controller", "eth0",
                                "wsg-bench", str(cycle), str(args.seconds)],
                               capture_output=True, text=True, timeout=args.seconds + 120)
            lines = [ln for ln in r.stdout.splitlines() if ln.startswith("{")]
            if not lines:
                print(f"{cycle:>4} ms  controller failed: {r.stderr.strip().splitlines()[-1:]}")
                continue
            res = json.loads(lines[-1])
            expiries = res["consumer_timeouts"] + (res["state"] != "running")
            held = expiries == 0 and res["jitter_p99"] <= 0.25 * cycle
            res.update(expiries=expiries, held=held)
            results.append(res)
            if expiries and args.sim_log:
                args.sim_log.with_suffix(f".controller-{cycle}ms.log").write_text(r.stderr)
            print(f"{cycle:>4} ms {res['frames']:>7} {expiries:>8} {res['jitter_p50']:>8.2f}/{res['jitter_p99']:.2f}/"
                  f"{res['jitter_max']:.2f}  {'yes' if held else 'no'}")
        sim.terminate()
        _, err = sim.communicate(timeout=20)
        aborts = err.count("ended: watchdog")
        if args.sim_log:
            args.sim_log.write_text(err)
        print(f"device watchdog expiries (ARs ended for want of output frames): {aborts}")
        held = [r["cycle_ms"] for r in results if r["held"]]
        print(f"shortest cycle held: {min(held)} ms" if held and not aborts else "no cycle held without expiry")
        print(f"load average after: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    finally:
        for h in hogs:
            h.kill()
            h.wait()
        if sim is not None and sim.poll() is None:
            sim.kill()
        for ns in (dev, ctl):
            subprocess.run(["ip", "netns", "del", ns], capture_output=True)


if __name__ == "__main__":
    main()
