"""Issue 23 items 7 and 8: a bad scenario file is one line and exit 2, never a traceback; loading and
serving a scenario is linear in its number of events. Costs are ratios within one test run."""

from __future__ import annotations

import time
from pathlib import Path

import pytest

from pywsg.device import ManualClock, VirtualGripper
from pywsg.testing.scenario import Scenario, ScenarioError, ScenarioRunner

from .conftest import wsg


def _events(n: int) -> str:
    """``n`` timed events and as many state-triggered ones: a long but ordinary story."""
    out = []
    for i in range(n):
        out.append(f'[[event]]\nat = {i * 0.01:.2f}\ndo = "heat"\ndelta_c = 0.001\n')
        out.append(f'[[event]]\nafter = "HOLDING"\ncycle = {i + 1}\ndelay = 0.5\ndo = "remove_part"\n')
    return "\n".join(out)


@pytest.mark.parametrize("text, expect", [
    (b"\xff\xfe[[event]]\n", "not UTF-8"),
    (b"x = " + b"[" * 500 + b"]" * 500 + b"\n", "not valid TOML"),
    (b'[[event]]\nat = 1' + b"0" * 400 + b'\ndo = "heat"\ndelta_c = 1\n', "at: must be"),
    (b'[[event]]\nat = 1' + b"0" * 5000 + b'\ndo = "heat"\ndelta_c = 1\n', "not valid TOML"),
    (b'[[event]]\nafter = "IDLE"\ndelay = 1' + b"0" * 400 + b'\ndo = "heat"\ndelta_c = 1\n', "delay: must be"),
    (b'[[event]]\nat = 1\ndo = "heat"\ndelta_c = 1' + b"0" * 400 + b"\n", "delta_c: must be a finite"),
    (b'[[event]]\nat = 1\ndo = "heat"\ndelta_c = [1]\n', "delta_c: must be a number"),
    (b'[[event]]\nbefore = 1' + b"0" * 400 + b'\ndo = "heat"\ndelta_c = 1\n', "before: must be a string"),
    (b'[[event]]\nat = 1\ndo = "heat"\ndelta_c = 1\ncycle = 1' + b"0" * 400 + b"\n", "cycle"),
])
def test_bad_scenario_file_is_one_clear_error(tmp_path: Path, text: bytes, expect: str) -> None:
    path = tmp_path / "bad.toml"
    path.write_bytes(text)
    with pytest.raises(ScenarioError) as info:
        Scenario.load(path)
    assert expect in str(info.value) and len(str(info.value)) < 400, str(info.value)


def test_wsg_sim_with_a_bad_scenario_exits_2_with_one_line(tmp_path: Path) -> None:
    path = tmp_path / "deep.toml"
    path.write_bytes(b"x = " + b"[" * 500 + b"]" * 500 + b"\n")
    r = wsg("sim", "--scenario", str(path), "--tcp-port", "0", "--web-port", "off")
    assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr
    errors = [line for line in r.stderr.splitlines() if line.startswith("Error:")]
    assert len(errors) == 1 and "not valid TOML" in errors[0] and len(r.stderr.splitlines()) <= 5, r.stderr


def _load_and_run(path: Path) -> float:
    """CPU seconds to load ``path``, build its runner and serve every timed event."""
    t0 = time.process_time()
    scenario = Scenario.load(path)
    clock = ManualClock()
    runner = ScenarioRunner(scenario, VirtualGripper("wsg50", clock=clock))
    runner.run_due(1e9)
    for _ in range(50):
        runner.state_changed(runner.gripper.snapshot().gripper_state.__class__.HOLDING, 0.0)
        runner.state_changed(runner.gripper.snapshot().gripper_state.__class__.IDLE, 0.0)
    assert runner.actions >= len(scenario.events) // 2
    return time.process_time() - t0


def test_scenario_cost_is_linear_in_its_events(tmp_path: Path) -> None:
    """Before: 2.5k / 5k / 10k events took 0.36 / 2.0 / 8.3 s (quadratic). Four times the events must
    cost well under the 16 times a quadratic loader would; the small file is the baseline."""
    small, big = tmp_path / "small.toml", tmp_path / "big.toml"
    small.write_text(_events(1000))
    big.write_text(_events(4000))
    _load_and_run(small)  # warm up imports and caches
    base = min(_load_and_run(small) for _ in range(2))
    cost = min(_load_and_run(big) for _ in range(2))
    assert cost < 8 * base, (cost, base)


# Issue 33 item 8: a typo'd event key is an error naming the file's line, not a parameter silently ignored.
@pytest.mark.parametrize("text, line, key", [
    ('[[event]]\nat = 1\ndo = "part"\nwidht = 20\n', 4, "widht"),
    ('description = "x"\n\n[[event]]\nat = 0\ndo = "heat"\ndelta_c = 1\n\n[[event]]\nbefore = "GRIP"\n'
     'do = "fault"\nkind = "power"\nfinger = 1\ntimout = 2\n', 13, "timout"),
    ('[[event]]\nat = 1\ndo = "remove_part"\nwidth = 3\n', 4, "width"),
])
def test_an_unknown_event_key_is_an_error_with_its_line(tmp_path: Path, text: str, line: int, key: str) -> None:
    path = tmp_path / "typo.toml"
    path.write_text(text)
    with pytest.raises(ScenarioError) as info:
        Scenario.load(path)
    assert str(info.value).startswith(f"{path}:{line}: ") and f"{key}: not a parameter" in str(info.value), info.value


def test_the_world_api_refuses_an_unknown_key_too() -> None:
    from pywsg.testing import WorldError, apply

    g = VirtualGripper("wsg50", clock=ManualClock())
    with pytest.raises(WorldError) as info:
        apply(g, "part", {"widht": 20})
    assert info.value.field == "widht"
    assert g.snapshot().part is None  # nothing was placed


# Issue 33 item 9: a `before` event fires on every matching request; what it keeps and reports is bounded.
def test_a_before_event_on_every_request_keeps_a_bounded_log(tmp_path: Path) -> None:
    from pywsg.protocol import CATALOG
    from pywsg.testing.scenario import LOG_LIMIT, REPORT_BURST

    path = tmp_path / "every.toml"
    path.write_text('[[event]]\nbefore = "GRIP"\ndo = "heat"\ndelta_c = 0\n')
    clock = ManualClock()
    told: list[str] = []
    runner = ScenarioRunner(Scenario.load(path), VirtualGripper("wsg50", clock=clock),
                            on_action=lambda _t, line: told.append(line))
    grip = next(c.id for c in CATALOG.values() if c.name == "GRIP_PART")
    n = 3 * LOG_LIMIT
    for _ in range(n):  # all at one instant: a flood
        runner.before_command(grip, clock.now)
    assert runner.actions == n and len(runner.log) == LOG_LIMIT
    assert len(told) == REPORT_BURST  # the rest counted, not printed
    clock.advance(10.0)
    runner.before_command(grip, clock.now)
    assert told[-2] == f"... {n - REPORT_BURST} more scenario action(s) not shown", told[-3:]
    assert told[-1].startswith("temperature changed")
