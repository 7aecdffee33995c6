"""An S7-style startup against the device on a veth wire (#31 item 15), with this project's own frame-by-frame
controller (``s7_controller.py``): DCP Identify and Set IP by name, LLDP both ways, Connect with the DAP's
interface and port submodules and the WSG module, PDEV writes, PrmEnd, ApplicationReady, cyclic data, a
diagnosis alarm acknowledged, ProviderState STOP and back, Release — then a restart that keeps I&M1.
tshark decodes the capture without a malformed frame (IEC 61158-6-10; the image: 002 §3.1, 003 §4.1)."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from pywsg.fieldbus import descriptions

from .conftest import DEVICE_IP, HERE, STATION, Wire
from .test_wire import Capture

pytestmark = pytest.mark.realtime   # real time on a real wire; each test has its own namespaces
S7 = HERE / "s7_controller.py"


@pytest.mark.skipif(shutil.which("tshark") is None, reason="tshark is not installed (scripts/test.sh installs it)")
def test_s7_style_startup_from_dcp_to_release(wire: Wire, tmp_path: Path) -> None:
    cap = Capture(wire, tmp_path / "s7.pcapng")
    settings = tmp_path / "settings.json"
    sim = wire.sim("--part", "22", "--settings", str(settings), ip=None)   # named, no IP yet: as delivered
    r = wire.controller(argv=[sys.executable, str(S7), wire.iface, "startup", STATION, DEVICE_IP], timeout=120)
    # DCP: found by name without an IP, then Set IP (BlockError 0)
    assert r["identify"] == {"mac": r["identify"]["mac"], "ip_before": "0.0.0.0", "name": STATION}, r  # type: ignore[index]
    assert r["set_ip"] == 0
    # LLDP from the device: chassis = NameOfStation, port-001.<name>, TTL 20, PNIO port status + chassis MAC
    lldp = r["device_lldp"]
    assert isinstance(lldp, dict)
    assert (lldp["chassis"], lldp["port"], lldp["ttl"]) == (STATION, f"port-001.{STATION}", 20)
    assert {"000ecf02", "000ecf05", "00120f01"} <= set(lldp["org"])
    # Connect with DAP, interface, port and WSG module: accepted as they are (no ModuleDiffBlock)
    assert r["connect"] == {"status": 0, "blocks": ["0x8101", "0x8102", "0x8102", "0x8103"]}
    # PDEV writes in one WriteMultiple, each accepted; I&M1 written; the neighbour is this controller
    assert r["write_multiple"] == {"status": 0, "each": [0, 0, 0]}
    assert r["im1_write"] == 0
    real = r["pd_port_data_real"]
    assert isinstance(real, dict)
    assert (real["status"], real["own_port"], real["peers"]) == (0, "port-001", 1), real
    assert (real["peer_port"], real["peer_station"]) == ("port-001", "plc-s7"), real
    assert r["pd_real_data"] == 0
    assert r["im0"] == {"status": 0, "order_id": "WSG 50", "im_supported": 0x1E}
    # PrmEnd done, then the device's ApplicationReady, answered: IOPS GOOD, DataStatus RUN
    assert r["prm_end"] == {"status": 0, "command": 0x0008}
    assert r["application_ready"] == {"block": "0x112", "command": 0x0002}
    assert r["inputs_after_ready"] == {"iops": 0x80, "status": 0x35}
    # the diagnosis alarm: FAST STOP appears, then disappears; both acknowledged, the device confirmed both
    alarms = r["alarms"]
    assert isinstance(alarms, list) and len(alarms) == 2, alarms
    assert [(a["slot"], a["subslot"], a["usi"], a["items"]) for a in alarms] == [
        (1, 1, 0x8000, [[0x010C, 1]]), (1, 1, 0x8000, [[0x010C, 2]])], alarms
    assert alarms[0]["type"] == 1 and alarms[1]["type"] in (1, 0x000C)   # 000Ch: #31 item 5 (pn-a)
    assert r["alarm_acks_confirmed"] == 2
    # cyclic data: homing done, the jog moves with the provider in RUN
    assert r["homed"] is True
    assert isinstance(r["jog_run_mm"], float) and r["jog_run_mm"] > 1.0, r
    # back in RUN after STOP: the AR goes on (frames, IOPS GOOD); Release: done, and the device stops sending
    after = r["after_run"]
    assert isinstance(after, dict) and after["frames"] > 5 and after["iops"] == 0x80, after   # ~60 in 1 s
    assert r["release"] == {"status": 0, "command": 0x0008}
    assert r["frames_after_release"] == 0
    cap.stop()
    err = sim.stop()
    assert "Traceback" not in err and "watchdog" not in err

    # tshark: the whole session, LLDP included, without a malformed frame or an error-level expert note
    q = subprocess.run(["tshark", "-r", str(cap.path), "-Y", "lldp || pn_dcp || pn_rt || pn_io || dcerpc",
                        "-T", "fields", "-e", "frame.number", "-e", "_ws.malformed", "-e", "_ws.expert.severity",
                        "-e", "frame.protocols"], capture_output=True, text=True, timeout=60)
    assert q.returncode == 0, q.stderr
    rows = [line.split("\t") for line in q.stdout.splitlines()]
    flagged = [row for row in rows if row[1] or any(int(x, 0) >= 0x00800000 for x in row[2].split(",") if x)]
    assert flagged == [] and sum("lldp" in row[3] for row in rows) >= 2
    # Wireshark reads the GSDML as `wsg gsd` writes it (003 §3.1's name, .gsdml): the cyclic frames' modules
    # get the GSDML's names
    descriptions.write_all(tmp_path / "gsd")
    q = subprocess.run(["tshark", "-r", str(cap.path), "-o", f"pn_io.pnio_ps_networkpath:{tmp_path / 'gsd'}",
                        "-Y", "pn_rt && pn_io.ioxs", "-V", "-c", "400"], capture_output=True, text=True, timeout=60)
    assert 'ModuleName: "WSG register space"' in q.stdout, q.stdout[-2000:]

    # I&M1 survives a restart (the settings file): a new process, found and addressed by name again
    sim = wire.sim("--settings", str(settings), ip=None)
    again = wire.controller(argv=[sys.executable, str(S7), wire.iface, "im", STATION, DEVICE_IP], timeout=60)
    assert again["status"] == 0 and again["im1"] == "S7 startup test".ljust(32) + "veth cell".ljust(22), again
    assert "Traceback" not in sim.stop()

    # #31 item 1: a provider in STOP gets substitute values (a zero image), so the jog stops while the PLC is in
    # STOP (IEC 61158-6-10; docs/fidelity.md)
    assert r["jog_stop_mm"] <= 0.2, f"ProviderState STOP: the jog went on {r['jog_stop_mm']} mm in 0.5 s"
