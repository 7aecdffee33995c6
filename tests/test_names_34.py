"""One name per state in `wsg plc-demo`'s steps, and "1 grip" in `wsg demo` (issue 34 item 8)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from pywsg.fieldbus.image import InputImage
from pywsg.fieldbus.plc import STEP_TEXT, GrippingCycle
from pywsg.protocol import GState, Status

WSG = str(Path(sys.executable).with_name("wsg"))


def test_plc_demo_step_line_names_the_gripping_state_once() -> None:
    """Step 6 waits for GRIPPING (002 App. D); the line that leaves it names the state the same way."""
    lines: list[str] = []
    cyc = GrippingCycle(log=lines.append, state=6)
    cyc.step(InputImage(gstate=GState.GRIPPING, status=int(Status.E_CMD_PENDING)), 0.0)
    assert lines == [f"step  6 ->  7: {STEP_TEXT[7]}  [GRIPPING, E_CMD_PENDING]"], lines
    assert "GRIPPING" in STEP_TEXT[6] and not any("GRASPING" in text for text in STEP_TEXT.values())


def test_demo_says_1_grip() -> None:
    r = subprocess.run(
        [WSG, "demo", "--tcp-port", "0", "--web-port", "0", "--modbus-port", "0", "--cycles", "1", "--hold", "0.1",
         "--speed", "400", "--exit"], capture_output=True, text=True, timeout=90)
    assert r.returncode == 0, r.stderr
    assert "gripping statistics: 1 grip, 0 no part, 0 lost" in r.stdout, r.stdout
