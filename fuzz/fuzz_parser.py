"""Coverage-guided fuzzing of the frame parser with atheris (run by hand, not in the test suite).

    .venv/bin/pip install atheris
    .venv/bin/python fuzz/fuzz_parser.py -max_total_time=60

Each input is cut into chunks by its first byte and fed to a device-side parser (per-ID SIZE caps)
and a client-side one. Any exception other than the parser's own events is a finding, and so is a
buffer that grows past one maximal frame.
"""

from __future__ import annotations

import sys

import atheris

with atheris.instrument_imports():
    from pywsg.protocol import MAX_PAYLOAD, FrameParser, parse_datagram
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


def main() -> None:
    atheris.Setup(sys.argv, test_one_input)
    atheris.Fuzz()


if __name__ == "__main__":
    main()
