"""Wireshark's verdict on PROFINET frames: write a pcap, let tshark decode it, list what it flags.

A frame is flagged when tshark marks it Malformed or raises Error-level expert info on it (warnings,
notes and chats are not flags: a refused request is a warning by design). Used on every capture the
PROFINET tests make (issue 31 item 9).
"""

from __future__ import annotations

import shutil
import struct
import subprocess
from pathlib import Path

import pytest

#: Expert-info severities (epan/proto.h): PI_ERROR is 0x00800000.
PI_ERROR = 0x00800000
needs_tshark = pytest.mark.skipif(shutil.which("tshark") is None,
                                  reason="tshark is not installed (scripts/test.sh installs it)")


def write_pcap(path: Path, frames: list[bytes]) -> Path:
    """A classic pcap (Ethernet link type) holding ``frames`` 1 ms apart."""
    out = [struct.pack("<IHHiIII", 0xA1B2C3D4, 2, 4, 0, 0, 65535, 1)]
    for i, f in enumerate(frames):
        out.append(struct.pack("<IIII", i // 1000, (i % 1000) * 1000, len(f), len(f)) + f)
    path.write_bytes(b"".join(out))
    return path


def flagged(path: Path, src_mac: str | None = None) -> list[dict[str, str]]:
    """Frames tshark finds Malformed or with Error-level expert info (``src_mac``: only frames from it)."""
    fields = {"number": "frame.number", "src": "eth.src", "protocols": "frame.protocols",
              "malformed": "_ws.malformed", "severity": "_ws.expert.severity", "message": "_ws.expert.message"}
    flt = "_ws.malformed || _ws.expert.severity >= 0x00800000"
    if src_mac:
        flt = f"eth.src == {src_mac} && ({flt})"
    r = subprocess.run(["tshark", "-n", "-r", str(path), "-Y", flt, "-T", "fields", "-E", "occurrence=a",
                        "-E", "separator=\t", *(a for f in fields.values() for a in ("-e", f))],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    return [dict(zip(fields, line.split("\t"), strict=False)) for line in r.stdout.splitlines() if line.strip()]


def counts(path: Path, display_filter: str) -> int:
    """How many frames of the capture match ``display_filter``."""
    r = subprocess.run(["tshark", "-n", "-r", str(path), "-Y", display_filter, "-T", "fields", "-e", "frame.number"],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    return len(r.stdout.split())
