"""The virtual WSG as a PROFINET IO device on a veth wire, against profinet-py as the controller
(issue 21; the device: RT_CLASS_1, conformance class A; the register image: 002 §3.1, 003 §4.1)."""

from __future__ import annotations

import shutil
import subprocess
import time
from pathlib import Path
from typing import ClassVar

import pytest

from .conftest import DEVICE_IP, STATION, WSG, Wire

pytestmark = pytest.mark.realtime   # real time on a real wire; each test has its own namespaces

IFACES = {"dea00001-6c97-11d1-8271-00a02442df7d": "pn_io_device",
          "dea00002-6c97-11d1-8271-00a02442df7d": "pn_io_controller"}
PN_FILTER = "pn_dcp || pn_rt || pn_io || pn_io_device || pn_io_controller"


class Capture:
    """tshark on the controller's side of the wire, writing a pcapng."""

    def __init__(self, wire: Wire, path: Path) -> None:
        self.path = path
        self.proc = wire.popen(wire.controller_ns, ["tshark", "-i", wire.iface, "-w", str(path), "-q"])
        deadline = time.monotonic() + 20
        assert self.proc.stderr is not None
        while time.monotonic() < deadline:
            line = self.proc.stderr.readline()
            if "Capturing on" in line or not line:
                break
        assert self.proc.poll() is None, "tshark did not start capturing"

    def stop(self) -> None:
        time.sleep(0.3)   # the last replies on the wire
        self.proc.terminate()
        self.proc.communicate(timeout=20)

    FIELDS: ClassVar[dict[str, str]] = {
              "number": "frame.number", "src": "eth.src", "proto": "dcerpc.dg_if_id",
              "dcp_service": "pn_dcp.service_id",
              "dcp_type": "pn_dcp.service_type", "index": "pn_io.index", "rpc_type": "dcerpc.pkt_type",
              "opnum": "dcerpc.opnum", "error": "pn_io.error_code", "command": "pn_io.control_command",
              "frame_id": "pn_rt.frame_id", "malformed": "_ws.malformed", "severity": "_ws.expert.severity"}

    def frames(self) -> list[dict[str, str]]:
        """Every PN-DCP, PN-RT and PNIO frame (ICMP quotes aside) as decoded fields; ``proto``: the PNIO
        dissector (pn_io_device / pn_io_controller) when there is one; ``severity``: warning or worse."""
        r = subprocess.run(["tshark", "-r", str(self.path), "-Y", f"({PN_FILTER}) && !icmp", "-T", "fields",
                            "-E", "occurrence=f", *(a for f in self.FIELDS.values() for a in ("-e", f))],
                           capture_output=True, text=True, timeout=60)
        assert r.returncode == 0, r.stderr
        out = []
        for line in r.stdout.splitlines():
            f = dict(zip(self.FIELDS, line.split("\t"), strict=False))
            f["proto"] = IFACES.get(f.get("proto", ""), f.get("proto", ""))
            # expert severity: 0x00800000 warning, 0x00c00000 error (chat and note are fine)
            f["severity"] = "" if not f.get("severity") or int(f["severity"], 0) < 0x00600000 else f["severity"]
            f.setdefault("malformed", "")
            out.append({k: f.get(k, "") for k in self.FIELDS})
        return out


@pytest.mark.skipif(shutil.which("tshark") is None, reason="tshark is not installed (scripts/test.sh installs it)")
def test_profinet_py_finds_reads_connects_and_runs_the_scl_cycle(wire: Wire, tmp_path: Path) -> None:
    """DCP Identify by name, I&M0, an AR built from pywsg's own GSDML, then 002 App. D's gripping cycle
    with a part placed; tshark decodes the whole session without a malformed or unknown PN packet."""
    cap = Capture(wire, tmp_path / "session.pcapng")
    sim = wire.sim("--part", "22")
    assert sim.banner["url"] == f"profinet://{wire.iface}/{STATION}"

    found = wire.controller("identify", STATION)
    assert found["name"] == STATION and found["ip"] == DEVICE_IP
    assert (found["vendor_id"], found["device_id"]) == (0x02A2, 0x0001)   # GSDML-02A2-0001-WSG.bmp (002 §2.2)
    assert "IO-Device" in str(found["roles"])
    im0 = found["im0"]
    assert isinstance(im0, dict)
    assert im0["vendor_id"] == 0x02A2 and im0["order_id"] == "WSG 50" and im0["serial"]

    # the manual's SCL gripping cycle as the user runs it: wsg plc-demo over profinet://
    url = f"profinet://{wire.iface}/{STATION}"
    done = wire.controller(argv=[*WSG, "plc-demo", "--url", url, "--cycles", "1", "--json"], timeout=90)
    # 002 §3.3's diagnosis on PROFINET: FAST STOP raised, then acknowledged -> appears / disappears
    diag = wire.controller("diag", STATION)
    try:
        assert done["event"] == "done" and done["ok"] is True, done
        assert done["cycles"] == 1 and done["holds"] == 1 and done["errors"] == 0, done
        assert diag["state"] == "running", diag
        # the last fault going is a "Diagnosis disappears" alarm (AlarmType 000Ch, Specifier 2)
        assert diag["alarms"] == [{"type": 1, "slot": 1, "subslot": 1, "items": [[0x010C, 1]]},
                                  {"type": 0x0C, "slot": 1, "subslot": 1, "items": [[0x010C, 2]]}], diag
    except AssertionError as exc:   # the device's log says why (an AR ended by a stalled controller, ...)
        raise AssertionError(f"{exc}\nsim log:\n{sim.stop()[-4000:]}\n"
                             f"plc-demo's log:\n{done.get('stdout')}\n{done.get('stderr')}\n"
                             f"diag controller's log:\n{diag.get('stderr')}") from None
    cap.stop()
    err = sim.stop()
    assert "Traceback" not in err

    frames = cap.frames()
    pn = [f for f in frames if f["malformed"] or f["severity"]]
    assert pn == [], f"malformed or flagged PROFINET frames: {pn}"

    def count(**want: str) -> int:
        return sum(all(f[k] == v for k, v in want.items()) for f in frames)

    assert count(dcp_service="5", dcp_type="1") >= 1              # DCP Identify response
    assert sum(f["index"] == "0xaff0" for f in frames) >= 2        # I&M0 read and answer
    for opnum in "0124":   # Connect, Release, Read, Control: answered with PNIOStatus OK by the device
        assert count(proto="pn_io_device", rpc_type="2", opnum=opnum, error="0x00"), opnum
    # the device's ApplicationReady (CControl to the controller) and the controller's Done
    assert count(proto="pn_io_controller", rpc_type="0", command="0x0002") >= 1
    assert count(proto="pn_io_controller", rpc_type="2", command="0x0008") >= 1
    alarms = [f for f in frames if f["frame_id"] and int(f["frame_id"], 0) == 0xFE01]
    assert len(alarms) >= 4   # DATA (alarm) and ACK both ways, decoded as PN-RTA without complaint
    rt = [f for f in frames if f["frame_id"] and 0xC000 <= int(f["frame_id"], 0) < 0xFC00]
    assert len(rt) > 50 and len({f["src"] for f in rt}) == 2   # cyclic RT frames both ways
