"""The README's test_station.py example works outside the checkout: the recorded session it replays ships
with the package (``pywsg.testing.SAMPLE_SESSION``), the same bytes as docs/examples/wsg-session.pcapng."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from pywsg.testing import SAMPLE_SESSION

ROOT = Path(__file__).resolve().parents[2]

# the README's example (test_station.py), as fixed for issue 34 item 10
STATION = '''
import pytest
from pywsg.testing import SAMPLE_SESSION

@pytest.mark.wsg_sim(clock="manual")
def test_field_session(wsg_sim):                   # recorded with `wsg proxy --pcap`
    wsg_sim.assert_replays(SAMPLE_SESSION)         # your own recording: its path
'''


def test_packaged_sample_is_the_docs_sample() -> None:
    assert SAMPLE_SESSION.read_bytes() == (ROOT / "docs" / "examples" / "wsg-session.pcapng").read_bytes()


def test_station_example_replays_from_any_directory(tmp_path: Path) -> None:
    (tmp_path / "test_station.py").write_text(STATION)
    r = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "test_station.py"],
                       cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert r.returncode == 0 and "1 passed" in r.stdout, r.stdout + r.stderr
