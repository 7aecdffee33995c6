"""World control from outside a running `wsg sim` (issue 14 item 2): `wsg world`, `--part/--block`,
the HTTP API with curl, and its access rules — all as subprocesses against a real `wsg sim`."""

from __future__ import annotations

import json
import subprocess
import urllib.error
import urllib.request
from pathlib import Path

from .conftest import SimProc, wsg


def test_wsg_world_commands_change_a_running_sim(sim_proc: type[SimProc]) -> None:
    sim = sim_proc()
    r = wsg("world", "--sim", sim.web, "--json", "part", "22", "--stiffness", "300")
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout)["state"]["part"] == 22.0
    # the driver, through the sim's TCP port, now grips the part (manual 000 §3.2.6: HOLDING)
    r = wsg("--url", sim.url, "home")
    assert r.returncode == 0, r.stderr + r.stdout
    r = wsg("--url", sim.url, "grip", "22", "--speed", "100")
    assert r.returncode == 0, r.stderr + r.stdout
    state = json.loads(wsg("world", "--sim", sim.web, "--json", "state").stdout)
    assert state["gripper_state"] == "HOLDING" and 21.0 < state["width"] <= 22.0
    r = wsg("world", "--sim", sim.web, "part", "--remove")
    assert r.returncode == 0 and "part removed" in r.stdout
    assert "PART_LOST" in wsg("world", "--sim", sim.web, "state").stdout
    r = wsg("world", "--sim", sim.web, "--json", "part", "40", "--inside")  # issue 24 item 7: a ring
    assert r.returncode == 0 and json.loads(r.stdout)["state"]["part_inside"] is True, r.stderr
    assert "inside" in json.loads(r.stdout)["action"]
    r = wsg("world", "--sim", sim.web, "--json", "part", "22")  # the default: from outside
    assert json.loads(r.stdout)["state"]["part_inside"] is False
    assert wsg("world", "--sim", sim.web, "block", "40").returncode == 0
    assert json.loads(wsg("world", "--sim", sim.web, "--json", "state").stdout)["blocked_at"] == 40.0
    assert wsg("world", "--sim", sim.web, "unblock").returncode == 0
    r = wsg("world", "--sim", sim.web, "heat", "35")
    assert r.returncode == 0 and json.loads(
        wsg("world", "--sim", sim.web, "--json", "state").stdout)["temperature"] >= 60
    r = wsg("world", "--sim", sim.web, "--json", "fault", "power", "on")
    assert json.loads(r.stdout)["state"]["fast_stop"] is True  # 000 Appendix B: SF_POWER_FAULT -> FAST STOP
    r = wsg("world", "--sim", sim.web, "--json", "fault", "finger", "on", "--finger", "2")
    assert "finger 2" in json.loads(r.stdout)["state"]["faults"]


def test_wsg_world_refuses_bad_input_and_says_why(sim_proc: type[SimProc]) -> None:
    sim = sim_proc()
    r = wsg("world", "--sim", sim.web, "part", "500")
    assert r.returncode == 1 and "width" in r.stderr and "stroke" in r.stderr
    r = wsg("world", "--sim", sim.web, "part")
    assert r.returncode == 2 and "WIDTH" in r.stderr
    r = wsg("world", "--sim", "http://127.0.0.1:1", "state")
    assert r.returncode == 3 and "cannot reach the sim" in r.stderr and "Traceback" not in r.stderr


def test_world_options_mean_the_same_everywhere(sim_proc: type[SimProc]) -> None:
    """Issue 16 item 9: a negative DELTA needs no `--`; `--json` after the subcommand as before it."""
    sim = sim_proc()
    before = json.loads(wsg("world", "--sim", sim.web, "--json", "state").stdout)["temperature"]
    r = wsg("world", "--sim", sim.web, "heat", "-10", "--json")
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout)["state"]["temperature"] <= before - 9
    r = wsg("world", "--sim", sim.web, "state", "--json")
    assert r.returncode == 0, r.stderr
    assert set(json.loads(r.stdout)) >= {"gripper_state", "temperature", "part"}
    r = wsg("world", "--sim", sim.web.removeprefix("http://"), "part", "20", "--json")  # HOST:PORT is http
    assert r.returncode == 0 and json.loads(r.stdout)["state"]["part"] == 20.0, r.stderr


def test_wsg_world_bad_sim_address_is_one_line_not_a_traceback() -> None:
    r = wsg("world", "--sim", "bogus.invalid", "state")
    assert r.returncode == 3 and "cannot reach the sim" in r.stderr and "Traceback" not in r.stderr, r.stderr
    r = wsg("world", "--sim", "tcp://127.0.0.1:1000", "state")  # the gripper's URL, not the web port's
    assert r.returncode == 2 and "--sim" in r.stderr and "http://HOST:PORT" in r.stderr, r.stderr
    assert "Traceback" not in r.stderr


def test_sim_part_at_start_makes_the_plc_demo_hold_parts(sim_proc: type[SimProc]) -> None:
    """The issue's reproduction: `wsg plc-demo --cycles 3` against `wsg sim --modbus-port N --part 20`."""
    sim = sim_proc("--part", "20", modbus=True)
    r = wsg("plc-demo", "--url", f"modbus-tcp://127.0.0.1:{sim.modbus_port}", "--cycles", "3", timeout=90)
    assert r.returncode == 0, r.stdout + r.stderr
    assert "3 parts held, 0 without part" in r.stdout


def test_sim_block_at_start(sim_proc: type[SimProc]) -> None:
    sim = sim_proc("--block", "35")
    state = json.loads(wsg("world", "--sim", sim.web, "--json", "state").stdout)
    assert state["blocked_at"] == 35.0 and state["part"] is None


def test_curl_example_from_the_docs_works_as_written(sim_proc: type[SimProc]) -> None:
    """The curl lines of docs/testing.md, run as written (only the port is this sim's, not 8080)."""
    doc = (Path(__file__).resolve().parents[2] / "docs" / "testing.md").read_text()
    lines = [ln for ln in doc.splitlines() if ln.startswith("curl ") and "127.0.0.1:8080" in ln]
    assert len(lines) == 3
    sim = sim_proc()
    port = sim.web.rsplit(":", 1)[1]
    replies = []
    for line in lines:
        out = subprocess.run(line.replace(":8080", f":{port}"), shell=True, capture_output=True, text=True,
                             timeout=20)
        assert out.returncode == 0, out.stderr
        replies.append(json.loads(out.stdout))
    assert replies[0]["ok"] is True and replies[0]["state"]["part"] == 22.0
    assert replies[1]["part"] == 22.0
    assert replies[2]["state"]["part"] is None


def _post(url: str, headers: dict[str, str]) -> int:
    req = urllib.request.Request(url, data=b'{"width": 20}', method="POST", headers=headers)
    try:
        with urllib.request.urlopen(req, timeout=10) as resp:
            return int(resp.status)
    except urllib.error.HTTPError as exc:
        return exc.code


def test_browsers_and_rebinding_hosts_are_refused(sim_proc: type[SimProc]) -> None:
    sim = sim_proc()
    url = sim.web + "/api/world/part"
    assert _post(url, {}) == 200
    assert _post(url, {"Origin": "http://evil.example"}) == 403            # a web page's fetch
    assert _post(url, {"Sec-Fetch-Site": "cross-site"}) == 403
    assert _post(url, {"Host": "evil.example:8080"}) == 400                 # DNS rebinding: the web's Host check
    assert _post(url, {"Host": "localhost"}) == 200
    # the browser pages' API still needs its CSRF token
    assert _post(sim.web + "/api/sim/part", {}) == 403


def test_a_sim_with_a_password_needs_it(tmp_path: Path) -> None:
    """Web password set (as on a sim bound beyond loopback): the world API wants it, wsg world sends it."""
    from pywsg.testing import SimThread

    with SimThread(web_port=0, web_options={"password": "s3cret"}) as sim:
        web = f"http://127.0.0.1:{sim.sim.web_port}"
        r = wsg("world", "--sim", web, "part", "20")
        assert r.returncode == 1 and "password required" in r.stderr and "--password" in r.stderr
        r = wsg("world", "--sim", web, "--password", "wrong", "part", "20")
        assert r.returncode == 1 and "wrong password" in r.stderr
        r = wsg("world", "--sim", web, "--password", "s3cret", "--json", "part", "20")
        assert r.returncode == 0, r.stderr
        assert json.loads(r.stdout)["state"]["part"] == 20.0
        out = subprocess.run(["curl", "-s", "-u", ":s3cret", web + "/api/world"], capture_output=True, text=True,
                             timeout=20)
        assert json.loads(out.stdout)["part"] == 20.0  # HTTP Basic with any user name works too
