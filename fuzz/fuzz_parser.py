"""Fuzz the frame parser (command manual 1.2.1 framing), device and client side.

    .venv/bin/pip install atheris
    .venv/bin/python fuzz/fuzz_parser.py -max_total_time=60
    .venv/bin/python fuzz/fuzz_parser.py --hypothesis --examples 5000   # without atheris

Each input is cut into chunks by its first byte and fed to a device-side parser (per-ID SIZE caps)
and a client-side one. Any exception other than the parser's own events is a finding, and so is a
buffer that grows past one maximal frame.
"""

from __future__ import annotations

import sys
from pathlib import Path

from hypothesis import strategies as st

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _harness import instrumented, main

with instrumented(__name__):
    from pywsg.protocol import MAX_PAYLOAD, FrameParser, encode_frame, parse_datagram
    from pywsg.protocol.catalog import request_max_payload
    from pywsg.protocol.decode import decode_bytes


def test_one_input(data: bytes) -> None:
    if not data:
        return
    chunk = data[0] % 32 + 1
    body = data[1:]
    for parser in (FrameParser(max_payload=request_max_payload), FrameParser(verify_checksum=False)):
        for i in range(0, len(body), chunk):
            parser.feed(body[i : i + chunk])
            if parser.buffered > MAX_PAYLOAD + 8 + chunk:
                raise AssertionError(f"parser buffers {parser.buffered} bytes")
    parse_datagram(body)
    decode_bytes(body)


_frame = st.builds(lambda cid, payload: encode_frame(cid, payload), st.integers(0, 255), st.binary(max_size=80))
_forged = st.builds(lambda cid, size: b"\xaa\xaa\xaa" + bytes([cid]) + size.to_bytes(2, "little"),
                    st.integers(0, 255), st.integers(0, 0xFFFF))
inputs = st.builds(lambda chunk, parts: bytes([chunk]) + b"".join(parts), st.integers(0, 255),
                   st.lists(st.one_of(_frame, _forged, st.binary(max_size=40)), max_size=12))
"""A chunking byte, then frames, forged headers and garbage."""


if __name__ == "__main__":
    main(test_one_input, inputs)
