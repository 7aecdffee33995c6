"""Every commander subcommand, human and --json output, error exits: the real `wsg` against `wsg sim`."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from .conftest import Sim, free_port, run_wsg


def test_info_state_limits_temp(sim: Sim) -> None:
    r = sim.wsg("info")
    assert r.code == 0, r
    assert "WSG50 (1)" in r.out and "firmware_version" in r.out
    info = sim.wsg("info", "--json").json()
    assert info["type"] == "WSG50" and isinstance(info["serial_number"], int)
    r = sim.wsg("state")
    assert r.code == 0 and " mm" in r.out and "mm/s" in r.out and " N" in r.out and "°C" in r.out, r
    st = sim.wsg("state", "--json").json()
    assert set(st) >= {"width", "speed", "force", "gripper_state", "flags", "temperature"}
    assert isinstance(st["flags"], list)
    lim = sim.wsg("limits", "--json").json()
    assert lim["stroke"] == pytest.approx(110.0) and lim["max_speed"] > lim["min_speed"] > 0
    assert "110.00 mm" in sim.wsg("limits").out
    temp = sim.wsg("temp", "--json").json()["temperature"]
    assert 0 < temp < 80
    assert sim.wsg("temp").out.strip().endswith("°C")


def test_motion_commands(sim: Sim) -> None:
    r = sim.wsg("home")
    assert r.code == 0 and r.out.startswith("home: done"), r
    r = sim.wsg("move", "30", "--speed", "400", "--json")
    assert r.code == 0, r
    assert r.json() == {"ok": True, "command": "move", "width": pytest.approx(30.0)}
    r = sim.wsg("move", "--relative", "--speed", "400", "--", "-10")
    assert r.code == 0 and "width 20.00" in r.out, r
    assert sim.wsg("width", "--json").json()["width"] == pytest.approx(20.0)
    r = sim.wsg("release", "--speed", "400", "--json")
    assert r.json()["width"] == pytest.approx(110.0)
    # no part between 110 mm and the nominal 10 mm: E_CMD_FAILED, exit 1, name and meaning on stderr
    r = sim.wsg("grip", "10", "--speed", "400", "--force", "20")
    assert r.code == 1, r
    assert "E_CMD_FAILED (18): Error while executing a command" in r.err
    assert sim.wsg("gripper-state", "--json").json()["gripper_state"] == "NO_PART"
    assert sim.wsg("force-limit", "--json").json()["force_limit"] == pytest.approx(20.0)
    r = sim.wsg("grip", "10", "--json")
    assert r.code == 1 and r.json()["status"] == "E_CMD_FAILED" and r.json()["ok"] is False


def test_fast_stop_and_ack(sim: Sim) -> None:
    assert sim.wsg("fast-stop").code == 0
    assert "SF_FAST_STOP" in sim.wsg("flags", "--json").json()["flags"]
    r = sim.wsg("move", "50")
    assert r.code == 1 and "E_ACCESS_DENIED (16): Access denied" in r.err, r
    r = sim.wsg("ack", "--json")
    assert r.code == 0 and r.json()["ok"] is True
    assert "SF_FAST_STOP" not in sim.wsg("flags", "--json").json()["flags"]
    assert sim.wsg("stop").out.strip() == "stop: done"


def test_settings_commands(sim: Sim) -> None:
    assert sim.wsg("accel", "1000", "--json").json() == {"acceleration": 1000.0}
    assert "1000.00 mm/s²" in sim.wsg("accel").out
    assert sim.wsg("force-limit", "35").out.strip() == "force_limit  35.00 N"
    assert sim.wsg("soft-limits", "5", "100", "--json").json() == {"minus": 5.0, "plus": 100.0}
    r = sim.wsg("move", "2")  # beyond the soft limit
    assert r.code == 1 and "E_RANGE_ERROR" in r.err, r
    assert sim.wsg("soft-limits", "--clear", "--json").json() == {"minus": None, "plus": None}
    assert sim.wsg("soft-limits", "5").code == 2  # MINUS without PLUS: usage error
    assert sim.wsg("overdrive", "on", "--json").json()["overdrive"] is True
    assert "SF_OVERDRIVE_MODE" in sim.wsg("flags", "--json").json()["flags"]
    assert sim.wsg("overdrive", "off").code == 0
    assert sim.wsg("tag", "set", "cell-7").code == 0
    assert sim.wsg("tag", "--json").json() == {"tag": "cell-7"}
    assert sim.wsg("tag", "get").out.split() == ["tag", "cell-7"]
    stats = sim.wsg("stats", "--json").json()
    assert set(stats) == {"total", "no_part", "lost_part"}
    assert sim.wsg("stats", "--reset").code == 0
    assert sim.wsg("stats", "--json").json()["total"] == 0


def test_finger_and_loop(sim: Sim) -> None:
    assert sim.wsg("finger", "1", "info", "--json").json() == {"type": "GENERIC", "data_size": 0}
    assert isinstance(sim.wsg("finger", "2", "flags", "--json").json()["flags"], list)
    assert sim.wsg("finger", "1", "power", "on", "--json").json() == {"power": "on"}
    r = sim.wsg("finger", "1", "data")
    assert r.code == 1 and "E_NOT_AVAILABLE (1): Function or data is not available" in r.err, r
    assert sim.wsg("finger", "3", "info").code == 2
    assert sim.wsg("loop", "1", "0x20", '"ok"', "--json").json() == {"sent": "01 20 6F 6B", "returned": "01 20 6F 6B",
                                                                      "equal": True}


def test_tare_error_and_connection_refused(sim: Sim) -> None:
    r = sim.wsg("tare", "--json")
    if r.code:  # the virtual gripper answers E_NOT_AVAILABLE (no force sensor to tare in its model)
        assert r.code == 1 and r.json()["status"] and r.json()["meaning"], r
    r = run_wsg("info", "--timeout", "1", url=f"tcp://127.0.0.1:{free_port()}")
    assert r.code == 3 and "cannot connect" in r.err, r
    r = run_wsg("info", "--json", "--timeout", "1", url=f"tcp://127.0.0.1:{free_port()}")
    assert r.code == 3 and r.json()["ok"] is False


def test_udp_url(sim: Sim) -> None:
    r = run_wsg("info", "--json", url=sim.udp_url)
    assert r.code == 0 and r.json()["type"] == "WSG50", r


def test_log_and_log_file(homed: Sim, tmp_path: Path) -> None:
    sim = homed
    logfile = tmp_path / "session.jsonl"
    r = sim.wsg("move", "60", "--speed", "400", "--log", "--log-file", str(logfile))
    assert r.code == 0, r
    lines = [ln for ln in r.err.splitlines() if " TX " in ln or " RX " in ln]
    tx = [ln for ln in lines if " TX 21h PREPOSITION" in ln]
    assert tx and "width=60 mm" in tx[0] and "speed=400 mm/s" in tx[0]
    assert any("RX 21h PREPOSITION" in ln and "E_CMD_PENDING" in ln and "1A 00" in ln for ln in lines)
    assert any("RX 21h PREPOSITION" in ln and "E_SUCCESS" in ln for ln in lines)
    entries = [json.loads(x) for x in logfile.read_text().splitlines()]
    assert {e["direction"] for e in entries} == {"tx", "rx"}
    assert [e["status"] for e in entries if e["command"] == "PREPOSITION"] == [None, "E_CMD_PENDING", "E_SUCCESS"]
    r = run_wsg("log", str(logfile))
    assert r.code == 0 and "TX 21h PREPOSITION" in r.out and "E_CMD_PENDING" in r.out, r
    assert len(r.out.splitlines()) == len(entries)
    r = run_wsg("log", "--json", str(logfile))
    assert [json.loads(x)["hex"] for x in r.out.splitlines()] == [e["hex"] for e in entries]


def test_log_session_from_stdin(sim: Sim) -> None:
    r = sim.wsg("log", "--subscribe", "width", "--period", "50", "--duration", "0.6",
                input="get-temperature\n0x24 \"ack\"\n")
    assert r.code == 0, r
    rx_width = [ln for ln in r.out.splitlines() if "RX 43h GET_OPENING_WIDTH" in ln]
    assert len(rx_width) >= 5, r  # ~12 auto-update packets in 0.6 s at 50 ms
    assert any("RX 46h GET_TEMPERATURE" in ln and "°C" in ln for ln in r.out.splitlines())
    assert any("TX 24h ACK_FAST_STOP" in ln and "key='ack'" in ln for ln in r.out.splitlines())
    r = sim.wsg("log", input="0x24 ack\n")
    assert r.code == 2 and '"ack"' in r.err


def test_help_explains_units_and_defaults() -> None:
    r = run_wsg("--help")
    assert r.code == 0 and "mm/s" in r.out and "monitor" in r.out and "send" in r.out
    text = " ".join(run_wsg("move", "--help").out.split())
    assert "mm/s" in text and "[default: 50.0" in text and "--stop-on-block" in text
    text = " ".join(run_wsg("grip", "--help").out.split())
    assert "--force N" in text and "in N" in text
    text = " ".join(run_wsg("monitor", "--help").out.split())
    assert "[default: 50" in text and " ms" in text


def test_shell_completion() -> None:
    r = run_wsg(env={"_WSG_COMPLETE": "bash_source"})
    assert r.code == 0 and "_wsg_completion" in r.out
    r = run_wsg(env={"_WSG_COMPLETE": "bash_complete", "COMP_WORDS": "wsg mo", "COMP_CWORD": "1"})
    assert "monitor" in r.out and "move" in r.out
    r = run_wsg(env={"_WSG_COMPLETE": "bash_complete", "COMP_WORDS": "wsg send get-sy", "COMP_CWORD": "2"})
    assert "get-system-state" in r.out and "get-system-info" in r.out


def test_group_level_log_and_json_options(sim: Sim) -> None:
    """`wsg --log --json move 60` works like `wsg move 60 --log --json`."""
    assert sim.wsg("home").code == 0
    r = sim.wsg("--log", "--json", "move", "60", "--speed", "400")
    assert r.code == 0, r
    assert any(" TX 21h PREPOSITION" in ln for ln in r.err.splitlines())
    assert abs(r.json()["width"] - 60.0) < 0.01
