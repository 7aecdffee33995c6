"""Codec speed: CRC ns per frame, encode frames/s, parse frames/s (14- and 266-byte frames).

Baselines measured in the same run: Appendix D's per-byte CRC loop, and the same parse with
the checksum check skipped. Run: .venv/bin/python benchmarks/bench_codec.py
"""

from __future__ import annotations

import json
import platform
import sys
import time
from collections.abc import Callable

from pywsg.protocol import FrameParser, crc16, crc16_bytewise, encode_frame


def rate(fn: Callable[[], object], min_time: float = 0.4) -> float:
    """Calls per second of ``fn``: best of 5 runs of at least ``min_time`` seconds each."""
    n = 1
    while True:
        t0 = time.perf_counter()
        for _ in range(n):
            fn()
        dt = time.perf_counter() - t0
        if dt >= min_time / 5:
            break
        n *= 2
    best = 0.0
    for _ in range(5):
        t0 = time.perf_counter()
        for _ in range(n):
            fn()
        best = max(best, n / (time.perf_counter() - t0))
    return best


def bench(size: int) -> dict[str, float]:
    payload = bytes(range(256)) * 2
    payload = payload[: size - 8]
    frame = encode_frame(0x06, payload)
    assert len(frame) == size
    batch = frame * 100
    body = frame[:-2]
    out: dict[str, float] = {}
    out["crc_ns"] = 1e9 / rate(lambda: crc16(body))
    out["crc_bytewise_ns"] = 1e9 / rate(lambda: crc16_bytewise(body))
    out["crc_speedup"] = out["crc_bytewise_ns"] / out["crc_ns"]
    out["encode_fps"] = rate(lambda: encode_frame(0x06, payload))
    verify = FrameParser(verify_checksum=True)
    skip = FrameParser(verify_checksum=False)
    out["parse_fps"] = 100 * rate(lambda: verify.feed(batch))
    out["parse_nocrc_fps"] = 100 * rate(lambda: skip.feed(batch))
    out["parse_ratio"] = out["parse_nocrc_fps"] / out["parse_fps"]
    return out


def main() -> None:
    results = {size: bench(size) for size in (14, 266)}
    if "--json" in sys.argv:
        print(json.dumps(results, indent=2))
        return
    print(f"# bench_codec  python {platform.python_version()}  {platform.machine()}  {platform.processor() or ''}")
    print(f"{'frame':>6} {'CRC ns':>9} {'bytewise ns':>12} {'speed-up':>9} {'encode/s':>11} "
          f"{'parse/s':>11} {'parse no-CRC/s':>15} {'no-CRC/CRC':>11}")
    for size, r in results.items():
        print(f"{size:>5}B {r['crc_ns']:9.0f} {r['crc_bytewise_ns']:12.0f} {r['crc_speedup']:8.1f}x "
              f"{r['encode_fps']:11.0f} {r['parse_fps']:11.0f} {r['parse_nocrc_fps']:15.0f} {r['parse_ratio']:10.2f}x")
    print("targets: CRC >= 3x the per-byte loop on 266 B; parse+verify of 14 B within 3x of the no-CRC parse")


if __name__ == "__main__":
    main()
