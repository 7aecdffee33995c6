"""``wsg sim --count N`` stops all its grippers together, names the descriptor limit it would hit, and refuses
``--time-scale nan`` as a usage error (issue 33 items 6 and 14).

Before: each gripper's web interface took ~0.2 s to stop, one after the other (200 grippers: 35.8 s on
SIGTERM, past a supervisor's stop timeout, so the settings were never saved); under ``ulimit -n 1024``,
``--count 200`` said "could not bind"; ``--time-scale nan`` printed a 33-line traceback.
"""

from __future__ import annotations

import os
import resource
import signal
import subprocess
import sys
import time

from click.testing import CliRunner

from pywsg.cli.main import cli

from ..ports import free_base
from ..simlog import tracebacks

WSG = [sys.executable, "-c", "from pywsg.cli.main import main; main()", "sim", "--json", "--no-uvloop"]


def _stop_time(count: int) -> float:
    """Seconds from SIGTERM to exit for ``wsg sim --count COUNT`` with every gripper's web interface on."""
    web = free_base(count)
    proc = subprocess.Popen(
        [*WSG, "--count", str(count), "--tcp-port", "0", "--udp-port", "0", "--serial", "off",
         "--web-port", str(web)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        env=dict(os.environ, PYTHONUNBUFFERED="1"))
    assert proc.stdout is not None
    seen = 0
    while seen < count:
        line = proc.stdout.readline()
        assert line, proc.stderr.read() if proc.stderr else ""
        seen += '"kind": "web"' in line
    t = time.monotonic()
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=60)
    took = time.monotonic() - t
    assert proc.returncode == 0 and not tracebacks(err), err
    return took


def test_count_grippers_stop_together_not_one_after_the_other() -> None:
    one = _stop_time(1)
    many = _stop_time(8)
    # one after the other: 8 x one (~1.6 s); together about one, whatever the machine's speed
    assert many < 3 * one + 0.3, (many, one)


def _limit_fds(n: int) -> None:
    resource.setrlimit(resource.RLIMIT_NOFILE, (n, n))


def test_count_over_the_descriptor_limit_names_the_limit_and_the_count_that_fits() -> None:
    proc = subprocess.run(
        [*WSG, "--count", "40", "--tcp-port", "0", "--udp-port", "0", "--web-port", "off", "--modbus-port", "0"],
        capture_output=True, text=True, timeout=60, preexec_fn=lambda: _limit_fds(128))
    assert proc.returncode == 1, proc.stderr
    err = proc.stderr
    assert "ulimit -n" in err and "may open 128" in err and "fits" in err, err
    fits = int(err.split("--count ")[2].split(" fits")[0])
    assert 0 < fits < 40
    assert not tracebacks(err), err


def test_time_scale_nan_is_a_usage_error() -> None:
    for value in ("nan", "NaN", "-nan"):
        r = CliRunner().invoke(cli, ["sim", "--time-scale", value])
        assert r.exit_code == 2, r.output
        assert "--time-scale" in r.output and "not a number" in r.output
        assert r.exception is None or isinstance(r.exception, SystemExit)
