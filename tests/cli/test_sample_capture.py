"""The sample capture the README decodes (docs/examples/wsg-session.pcapng) and the script that makes it.

The shipped file is what ``scripts/make-sample-capture.sh`` records; this test records a fresh one the
same way and checks that both decode to the same conversation, so the sample stays true.
"""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

import pytest

from .conftest import WSG, run_wsg

ROOT = Path(__file__).resolve().parents[2]
SAMPLE = ROOT / "docs" / "examples" / "wsg-session.pcapng"
SCRIPT = ROOT / "scripts" / "make-sample-capture.sh"

def _cmd(name: str, *replies: str) -> list[tuple[str, str, str | None]]:
    return [("request", name, None), *(("reply", name, r) for r in replies)]


BYE = _cmd("DISCONNECT", "E_SUCCESS")  # every `wsg` command ends by announcing its disconnect (07h)
CONVERSATION = [
    *_cmd("HOMING", "E_CMD_PENDING", "E_SUCCESS"), *_cmd("GET_OPENING_WIDTH", "E_SUCCESS"), *BYE,   # wsg home
    *_cmd("GET_SYSTEM_LIMITS", "E_SUCCESS"),                       # wsg move 40: checks 40 mm against the stroke
    *_cmd("PREPOSITION", "E_CMD_PENDING", "E_SUCCESS"), *_cmd("GET_OPENING_WIDTH", "E_SUCCESS"), *BYE,
    *_cmd("GET_OPENING_WIDTH", "E_SUCCESS"), *BYE,                 # wsg width
    *_cmd("UNKNOWN_90h", "E_CMD_UNKNOWN"), *BYE,                   # wsg send 0x90
]


def _conversation(path: Path) -> list[tuple[str, str, str | None]]:
    r = run_wsg("decode", "--json", "-f", str(path))
    assert r.code == 0, r
    return [(f["direction"], f["command"], f["status"]) for f in json.loads(r.out)]


def test_the_shipped_sample_decodes_as_documented() -> None:
    assert SAMPLE.stat().st_size < 16_000  # small enough to ship
    assert _conversation(SAMPLE) == CONVERSATION
    text = run_wsg("decode", "-f", str(SAMPLE)).out
    assert "reply PREPOSITION (21h)" in text and "width: 40 mm" in text


@pytest.mark.realtime
@pytest.mark.skipif(shutil.which("dumpcap") is None, reason="dumpcap (tshark) not installed")
def test_the_script_records_the_same_conversation(tmp_path: Path) -> None:
    out = tmp_path / "fresh.pcapng"
    r = subprocess.run(["bash", str(SCRIPT), str(out)], capture_output=True, text=True, timeout=120,
                       env={"PATH": f"{WSG.parent}:/usr/bin:/bin", "WSG": str(WSG)})
    if r.returncode != 0 and "permission" in r.stderr.lower():
        pytest.skip(f"dumpcap cannot capture here: {r.stderr.strip()}")
    assert r.returncode == 0, r.stderr
    assert _conversation(out) == CONVERSATION
