"""The web interface with a running DP slave: the Fieldbus Monitor's Bus State (003 §6) from the
adapter's bus_state(), and Settings → Command Interface setting the station address (002 §2.1.2)."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import httpx
import pytest

from pywsg.fieldbus.profibus.dp import DpState

from ...simthread import SimThread
from .conftest import adapter
from .pbmaster import dp_master, run_until, start

pytestmark = pytest.mark.realtime


def _client(sim: SimThread) -> httpx.Client:
    c = httpx.Client(base_url=f"http://127.0.0.1:{sim.g.web_port}", timeout=10.0)
    c.headers["X-CSRF-Token"] = c.get("/api/csrf").json()["token"]
    return c


def _bus_state(c: httpx.Client) -> dict[str, str]:
    buses = c.get("/api/fieldbus").json()["buses"]
    pb = [b for b in buses if b["name"] == "PROFIBUS DP"]
    assert pb, buses
    return {r["label"]: r["text"] for r in pb[0]["rows"]}


def test_bus_state_and_station_address_from_the_settings_page(
        pb_factory: Callable[..., SimThread], tmp_path: Path) -> None:
    settings = tmp_path / "s.json"
    (tmp_path / "s.interface.json").write_text(json.dumps({"profibus_address": 7, "profibus_address_locked": True}))
    sim = pb_factory(tcp_port=None, udp_port=None, profibus="pty", web_port=0, settings=settings)
    ad = adapter(sim)
    c = _client(sim)
    try:
        state = _bus_state(c)
        assert state["Station Address"] == "7" and state["Bitrate"].startswith("19.2 kbit/s")
        assert state["Interface state"].startswith("Waiting for parameters (Wait_Prm)")
        with dp_master(ad.path) as (master, desc):
            start(master, desc)
            run_until(master, desc, lambda d: d is not None, "Data_Exch")
            assert _bus_state(c)["Interface state"] == "Online"
            body = c.get("/api/interface").json()
            assert "Applied at once" in body["notes"]["profibus_address"]
            r = c.post("/api/interface", json={"profibus_address": 12})
            assert r.status_code == 200, r.text
        assert ad.address == 12 and ad.slave.state is DpState.WAIT_PRM
        assert _bus_state(c)["Station Address"] == "12"
        stored = json.loads((tmp_path / "s.interface.json").read_text())
        assert stored["profibus_address"] == 12
        assert stored["profibus_address_locked"] is True      # the web page keeps the slave's No_Add_Chg
        # The master now finds the slave at 12.
        with dp_master(ad.path, address=12) as (master, desc):
            start(master, desc)
            run_until(master, desc, lambda d: d is not None, "Data_Exch at address 12")
    finally:
        c.close()
