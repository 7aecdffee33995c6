"""Substitute values on the wire (issue 31 item 1): profinet-py holds JOG+/JOG- in the output image, then
sends the same image with DataStatus ProviderState STOP (25h), then with IOPS BAD; the fingers must stand
still in both (IEC 61158-6-10: data from a provider in STOP or with IOPS BAD is not used; docs/fidelity.md
"Substitute values"), and move again once the controller is back in RUN with GOOD data (002 §4.7: jog is a
level)."""

from __future__ import annotations

from pathlib import Path

import pytest

from .conftest import STATION, Wire
from .test_wire import Capture
from .tshark import flagged, needs_tshark

pytestmark = pytest.mark.realtime


@needs_tshark
def test_provider_stop_and_iops_bad_stop_the_jog_on_the_wire(wire: Wire, tmp_path: Path) -> None:
    cap = Capture(wire, tmp_path / "substitute.pcapng")
    sim = wire.sim("-v")
    r = wire.controller("substitute", STATION, timeout=90)
    cap.stop()

    def moved(phase: str) -> float:
        a, b = r[phase]   # type: ignore[misc]
        return abs(float(b) - float(a))

    # the baseline from the same run: RUN + GOOD with the jog level held moves the fingers (20 mm/s, 1 s)
    err = sim.stop()
    assert r["state"] == "running", (r, err[-3000:])
    assert moved("run") > 5.0, r
    assert moved("stop") < 0.05 and moved("iops_bad") < 0.05, r
    assert moved("run_again") > 5.0, r
    assert "ProviderState STOP" in err and "IOPS BAD" in err and "substitute values" in err
    assert "Traceback" not in err
    assert flagged(cap.path) == []   # the session, STOP frames and alarms included, decodes clean (item 9)
