"""FDL telegrams (IEC 61158-4-3): encoding checked against pyprofibus's own FDL codec, and a receiver
that frames by idle time: a telegram starts only after an idle line, a telegram cut off by an idle
line is dropped, and after an error nothing is read until the line goes idle; bad FCS, bad framing and
stray bytes cost no crash and bounded time."""

from __future__ import annotations

import os
import random
import time

import pytest

from pywsg.fieldbus.profibus import fdl

from .pbmaster import pyprofibus

FdlTelegram = pyprofibus.fdl.FdlTelegram


def _one(data: bytes) -> fdl.Telegram:
    events = fdl.FdlParser().feed(data)
    assert len(events) == 1 and isinstance(events[0], fdl.Telegram), events
    return events[0]


def test_sd1_fdl_status_request_bytes() -> None:
    """SD1: 10 DA SA FC FCS 16, FCS = (DA + SA + FC) mod 256."""
    raw = fdl.encode(7, 2, 0x49)
    assert raw == bytes([0x10, 0x07, 0x02, 0x49, 0x52, 0x16])
    assert bytes(pyprofibus.fdl.FdlTelegram_FdlStat_Req(da=7, sa=2).getRawData()) == raw


@pytest.mark.parametrize("du_len", [0, 1, 7, 8, 9, 12, 200, 244])
def test_our_encoding_is_what_pyprofibus_reads(du_len: int) -> None:
    """SD1 (no data), SD3 (8 bytes), SD2 (the rest) with SAPs, decoded by pyprofibus byte for byte."""
    du = bytes(range(du_len))
    raw = fdl.encode(2, 7, 0x08, du, dsap=62, ssap=60)
    t = FdlTelegram.fromRawData(bytearray(raw))
    assert (t.da, t.sa, t.fc) == (2, 7, 0x08)
    assert bytes(t.du) == du and bytes(t.dae) == b"\x3e" and bytes(t.sae) == b"\x3c"
    plain = fdl.encode(2, 7, 0x08, du)
    expect_sd = {0: fdl.SD1, 8: fdl.SD3}.get(du_len, fdl.SD2)
    assert plain[0] == expect_sd
    assert bytes(FdlTelegram.fromRawData(bytearray(plain)).du or b"") == du


def test_we_read_what_pyprofibus_encodes() -> None:
    """A Set_Prm (SD2 with DAE/SAE) and a Data_Exchange with 8 bytes (SD3) built by pyprofibus."""
    prm = pyprofibus.dp.DpTelegram_SetPrm_Req(da=7, sa=2)
    prm.identNumber = 0x5555
    t = _one(bytes(prm.toFdlTelegram().getRawData()))
    assert (t.da, t.sa, t.dsap, t.ssap) == (7, 2, 61, 62)
    assert t.data[4:6] == b"\x55\x55" and t.sd == fdl.SD2
    dx = pyprofibus.dp.DpTelegram_DataExchange_Req(da=7, sa=2, du=bytes(range(8)))
    t = _one(bytes(dx.toFdlTelegram().getRawData()))
    assert t.sd == fdl.SD3 and t.dsap is None and t.data == bytes(range(8))


def test_bad_fcs_bad_end_delimiter_and_bad_length_give_no_telegram() -> None:
    good = fdl.encode(7, 2, 0x7D, bytes(12), dsap=60, ssap=62)
    bad_fcs = good[:-2] + bytes([(good[-2] + 1) & 0xFF]) + good[-1:]
    bad_ed = good[:-1] + b"\x17"
    bad_le = bytes([0x68, good[1], good[1] + 1]) + good[3:]
    p = fdl.FdlParser()
    for junk in (bad_fcs, bad_ed, bad_le):
        events = p.feed(junk, idle=True)
        assert events and all(isinstance(e, fdl.LineError) for e in events), events
        assert not p.in_step
    # Without an idle line the good telegram is not taken; after one it is read whole.
    assert p.feed(good) == [] and p.dropped == len(good)
    assert p.feed(good, idle=True) == [_one(good)]


def test_torn_telegram_waits_for_its_rest_and_tokens_and_acks_are_ignored() -> None:
    good = fdl.encode(7, 2, 0x5D, bytes(range(8)))
    p = fdl.FdlParser()
    assert p.feed(good[:5]) == [] and p.pending == 5
    assert p.feed(good[5:]) == [_one(good)]
    # A token and a short ack are other stations' telegrams: passed over, the receiver stays in step.
    assert p.feed(bytes([fdl.SD4, 7, 2, fdl.SC]) + good) == [_one(good)]
    assert p.errors == 0


def test_a_length_byte_never_allocates_what_it_claims() -> None:
    """An SD2 header claiming 249 bytes then silence: the parser holds what arrived, nothing more."""
    p = fdl.FdlParser()
    p.feed(bytes([0x68, 249, 249, 0x68, 7, 2]))
    assert p.pending == 6


def test_a_telegram_cut_off_by_an_idle_line_is_dropped_and_the_next_one_read() -> None:
    """IEC 61158-4-3: a telegram ends at an idle line. A header claiming 249 bytes, then the line goes
    idle: the next request is read whole, not swallowed as the cut-off telegram's data unit."""
    p = fdl.FdlParser()
    request = fdl.encode(7, 2, 0x49)
    assert p.feed(bytes([0x68, 249, 249, 0x68, 7, 2, 0x6D])) == []
    events = p.feed(request * 3, idle=True)
    assert events[0] == fdl.LineError("cut off by an idle line", 7)
    assert events[1:] == [_one(request)] * 3


def test_a_telegram_inside_a_frame_with_a_corrupted_length_byte_is_not_taken() -> None:
    """An SD2 whose LE byte was hit on the line carries a whole FDL status request to station 7 in
    its data unit: a receiver that resynchronises on the next delimiter would answer it. Out of step
    after the bad header, nothing is read until the line goes idle."""
    inner = fdl.encode(7, 2, 0x49)
    frame = bytearray(fdl.encode(9, 2, 0x7D, b"\x00" + inner + b"\x00", dsap=60, ssap=62))
    frame[1] ^= 0x01                                   # LE no longer equals LEr
    p = fdl.FdlParser()
    events = p.feed(bytes(frame), idle=True)
    assert [e for e in events if isinstance(e, fdl.Telegram)] == []
    assert events == [fdl.LineError("bad SD2 header", len(frame))]
    frame[1] = frame[2] = frame[1] + 3                 # both length bytes wrong the same way
    events = p.feed(bytes(frame), idle=True)
    assert [e for e in events if isinstance(e, fdl.Telegram)] == []


GARBAGE = {
    "random": random.Random(5).randbytes(2**20),
    "SD2 header runs": b"\x68" * 2**20,                # every byte starts a plausible SD2 header
    "SD1 runs": b"\x10" * 2**20,
    "SD3 runs": b"\xa2" * 2**20,
    "short acks": b"\xe5" * 2**20,
    "SD2, bad FCS": b"\x68\x04\x04\x68\x07\x02\x4d\x00\x00\x16" * (2**20 // 10),
}


def _cost(data: bytes) -> tuple[float, int]:
    """(CPU seconds, telegrams) to parse ``data`` in 4 KiB reads."""
    p = fdl.FdlParser()
    t0 = time.process_time()
    for i in range(0, len(data), 4096):
        p.feed(data[i:i + 4096], idle=i == 0)   # one stream: after an error all is dropped
    return time.process_time() - t0, p.telegrams


def test_one_mib_of_garbage_costs_no_more_than_one_mib_of_telegrams() -> None:
    """Bounded CPU: 1 MiB of each kind of noise, in 4 KiB reads, costs at most a few times what 1 MiB
    of valid Data_Exchange telegrams costs, measured in this test; none of it reads as a telegram."""
    tel = fdl.encode(7, 2, 0x7D, bytes(range(8)))
    valid = tel * (2**20 // len(tel))
    runs = [_cost(valid) for _ in range(2)]
    assert all(n == len(valid) // len(tel) for _, n in runs)
    base = min(t for t, _ in runs)
    for kind, garbage in GARBAGE.items():
        spent, telegrams = min(_cost(garbage) for _ in range(2))
        assert telegrams == 0, kind
        assert spent < 4 * base + 0.02, f"{kind}: {spent:.3f} s against {base:.3f} s for valid telegrams"


def test_random_bytes_never_raise() -> None:
    p = fdl.FdlParser()
    for k in range(200):
        p.feed(os.urandom(random.randrange(1, 300)), idle=k % 3 == 0)
    assert p.pending <= fdl.MAX_TELEGRAM
