"""Saving the Communication Log: JSON lines (``wsg --log-file``'s format) and pcapng (``wsg proxy --pcap``'s).

Both are what ``wsg decode -f``, ``wsg log`` and ``wsg replay`` read back. A pcapng needs IP
packets: the frames go into synthetic IPv4 packets between placeholder addresses from TEST-NET-1
(RFC 5737: 192.0.2.1 the Commander, 192.0.2.2 the gripper) on the factory ports: TCP 1000 (opened
with a SYN, so the reader knows which side is the gripper) for TCP, serial and CAN links, UDP
1501 -> 1500 for UDP. The payload bytes are the frames exactly as sent and received.
"""

from __future__ import annotations

import json
import os
import tempfile
from collections.abc import Iterable

from ...capture.commlog import LogEntry
from ...capture.pcap import PcapWriter

__all__ = ["COMMANDER", "GRIPPER", "to_jsonl", "to_pcapng"]

COMMANDER = "192.0.2.1"
GRIPPER = "192.0.2.2"
TCP_PORT = 1000
UDP_PORT = 1500
UDP_REPLY_PORT = 1501
CLIENT_PORT = 49152


def to_jsonl(entries: Iterable[LogEntry]) -> str:
    """One JSON object per frame (time, direction, hex, decoded fields), as ``wsg --log-file`` writes."""
    return "".join(json.dumps(e.to_json(), ensure_ascii=False) + "\n" for e in entries)


def to_pcapng(entries: Iterable[LogEntry], scheme: str) -> bytes:
    """The frames as a pcapng capture; ``scheme``: the link's (``udp`` gives UDP datagrams, else TCP)."""
    fd, path = tempfile.mkstemp(suffix=".pcapng")
    os.close(fd)
    try:
        w = PcapWriter(path)
        try:
            items = list(entries)
            if scheme == "udp":
                me, it = (COMMANDER, UDP_REPLY_PORT), (GRIPPER, UDP_PORT)
                for e in items:
                    src, dst = (me, it) if e.direction == "tx" else (it, me)
                    w.udp(src, dst, e.decoded.raw, e.time)
            else:
                me, it = (COMMANDER, CLIENT_PORT), (GRIPPER, TCP_PORT)
                w.tcp_open(me, it, items[0].time if items else 0.0)
                for e in items:
                    src, dst = (me, it) if e.direction == "tx" else (it, me)
                    w.tcp(src, dst, e.decoded.raw, e.time)
        finally:
            w.close()
        with open(path, "rb") as f:
            return f.read()
    finally:
        os.unlink(path)
