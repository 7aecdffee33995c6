"""The README's main job: ``wsg demo`` runs a virtual gripper with its web interface and gripping cycles."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

WSG = str(Path(sys.executable).with_name("wsg"))


def test_demo_runs_gripping_cycles_against_the_virtual_gripper() -> None:
    r = subprocess.run(
        [WSG, "demo", "--tcp-port", "0", "--web-port", "0", "--modbus-port", "0", "--cycles", "2", "--hold", "0.1",
         "--speed", "400", "--exit", "--json"],
        capture_output=True, text=True, timeout=90,
    )
    assert r.returncode == 0, r.stderr
    events = [json.loads(line) for line in r.stdout.splitlines()]
    kinds = {e["kind"]: e for e in events if e["event"] == "interface"}
    assert kinds["tcp"]["url"].startswith("tcp://127.0.0.1:")
    assert kinds["web"]["url"].startswith("http://127.0.0.1:")
    steps = [e for e in events if e["event"] == "step"]
    grips = [s for s in steps if s["step"].startswith("grip")]
    assert len(grips) == 2 and all(s["state"] == "HOLDING" for s in grips)
    assert all(abs(s["width"] - 30.0) < 0.5 and s["force"] > 0 for s in grips)
    holds = [s for s in steps if s["step"].startswith("hold")]
    assert len(holds) == 2 and all(s["state"] == "HOLDING" and s["seconds"] >= 0.1 for s in holds)  # --hold 0.1
    releases = [s for s in steps if s["step"].startswith("release")]
    assert all(s["state"] == "IDLE" and abs(s["width"] - 60.0) < 0.01 for s in releases)
    stats = next(e for e in events if e["event"] == "statistics")
    assert stats == {"event": "statistics", "total": 2, "no_part": 0, "lost_part": 0}
