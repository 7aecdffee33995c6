"""Bytes in, frames out: parse errors answer with the status the manual names (000 §1.2.1, §3.1.1,
Appendix A; docs/fidelity.md where it is silent); sessions' rules."""

from __future__ import annotations

import struct

from pywsg.device import Settings
from pywsg.protocol import Frame, FrameParser, Status, SystemFlag, encode_frame

from .devrig import Rig, make_rig

S = Status


def statuses(frames: list[Frame]) -> list[tuple[int, Status | int]]:
    return [(f.command_id, f.status) for f in frames]


def test_feed_in_pieces_and_garbage(rig: Rig) -> None:
    wire = b"\x00\x13garbage" + encode_frame(0x06, b"hi") + encode_frame(0x31)
    out: list[Frame] = []
    for i in range(len(wire)):
        out.extend(rig.g.feed(rig.s, wire[i:i + 1]))
    assert statuses(out) == [(0x06, S.E_SUCCESS), (0x31, S.E_SUCCESS)]
    assert out[0].params == b"hi"


def test_checksum_error_answers_with_that_id_and_does_not_execute(homed: Rig) -> None:
    bad = bytearray(encode_frame(0x21, bytes([0]) + struct.pack("<ff", 10.0, 50.0)))
    bad[-1] ^= 0xFF
    assert statuses(homed.g.feed(homed.s, bytes(bad))) == [(0x21, S.E_CHECKSUM_ERROR)]
    assert not homed.g.moving()
    assert homed.flags() & SystemFlag.SF_CMD_FAILURE


def test_crc_check_disabled_accepts_any_checksum() -> None:
    r = make_rig(settings=Settings(crc_check=False))
    wire = bytearray(encode_frame(0x06, b"x"))
    wire[-2:] = b"\x00\x00"
    out = r.g.feed(r.s, bytes(wire))
    assert statuses(out) == [(0x06, S.E_SUCCESS)]
    assert FrameParser().feed(out[0].encode())[0] == out[0]  # replies always carry a valid CRC


def test_crc_setting_is_live(rig: Rig) -> None:
    wire = bytearray(encode_frame(0x06, b"x"))
    wire[-2:] = b"\x00\x00"
    assert statuses(rig.g.feed(rig.s, bytes(wire))) == [(0x06, S.E_CHECKSUM_ERROR)]
    rig.g.apply_settings(rig.g.settings.updated(crc_check=False))
    assert statuses(rig.g.feed(rig.s, bytes(wire))) == [(0x06, S.E_SUCCESS)]


def test_frame_too_large_is_format_error(rig: Rig) -> None:
    header = b"\xaa\xaa\xaa\x21" + struct.pack("<H", 900)
    assert statuses(rig.g.feed(rig.s, header)) == [(0x21, S.E_CMD_FORMAT_ERROR)]
    # the stream recovers at the next preamble
    assert statuses(rig.g.feed(rig.s, bytes(20) + encode_frame(0x31))) == [(0x31, S.E_SUCCESS)]


def test_frame_too_large_for_unknown_id_is_cmd_unknown(rig: Rig) -> None:
    header = b"\xaa\xaa\xaa\x99" + struct.pack("<H", 2000)
    assert statuses(rig.g.feed(rig.s, header)) == [(0x99, S.E_CMD_UNKNOWN)]


def test_loop_longer_than_256_is_format_error_on_the_wire(rig: Rig) -> None:
    assert statuses(rig.g.feed(rig.s, encode_frame(0x06, bytes(300)))) == [(0x06, S.E_CMD_FORMAT_ERROR)]


def test_wrong_payload_length_is_format_error(rig: Rig) -> None:
    assert statuses(rig.g.feed(rig.s, encode_frame(0x20, b""))) == [(0x20, S.E_CMD_FORMAT_ERROR)]
    assert statuses(rig.g.feed(rig.s, encode_frame(0x43, b"\x00"))) == [(0x43, S.E_CMD_FORMAT_ERROR)]


def test_payload_to_no_parameter_command(rig: Rig) -> None:
    assert statuses(rig.g.feed(rig.s, encode_frame(0x50, b"\x01\x02"))) == [(0x50, S.E_NO_PARAM_EXPECTED)]
    assert statuses(rig.g.feed(rig.s, encode_frame(0x22, b"\x01"))) == [(0x22, S.E_NO_PARAM_EXPECTED)]


def test_unknown_id(rig: Rig) -> None:
    assert statuses(rig.g.feed(rig.s, encode_frame(0x90))) == [(0x90, S.E_CMD_UNKNOWN)]
    assert rig.g.feed(rig.s, encode_frame(0x90))[0].encode() == bytes.fromhex("AAAAAA9002000E00FD02")


def test_fast_stop_is_never_refused(homed: Rig) -> None:
    assert statuses(homed.g.feed(homed.s, encode_frame(0x23, b"\x01"))) == [(0x23, S.E_SUCCESS)]
    assert homed.flags() & SystemFlag.SF_FAST_STOP


def test_datagram(rig: Rig) -> None:
    u = rig.g.open_session("udp", peer="127.0.0.1:1501")
    assert statuses(rig.g.handle_datagram(u, encode_frame(0x06, b"ab"))) == [(0x06, S.E_SUCCESS)]
    bad = bytearray(encode_frame(0x31))
    bad[-1] ^= 1
    assert statuses(rig.g.handle_datagram(u, bytes(bad))) == [(0x31, S.E_CHECKSUM_ERROR)]
    assert statuses(rig.g.handle_datagram(u, encode_frame(0x31)[:-3])) == [(0x31, S.E_CMD_FORMAT_ERROR)]
    assert statuses(rig.g.handle_datagram(u, encode_frame(0x07))) == [(0x07, S.E_NOT_AVAILABLE)]


def test_second_tcp_client_denied_until_first_leaves(rig: Rig) -> None:
    other = rig.g.open_session("tcp", peer="10.0.0.2:4000")
    assert statuses(rig.g.feed(other, encode_frame(0x50))) == [(0x50, S.E_ACCESS_DENIED)]
    assert statuses(rig.g.feed(rig.s, encode_frame(0x50))) == [(0x50, S.E_SUCCESS)]
    rig.g.feed(rig.s, encode_frame(0x07))
    rig.g.close_session(rig.s)
    third = rig.g.open_session("tcp", peer="10.0.0.3:4000")
    assert statuses(rig.g.feed(third, encode_frame(0x50))) == [(0x50, S.E_SUCCESS)]
    assert not rig.g.fast_stopped  # announced


def test_unannounced_tcp_close_raises_fast_stop(homed: Rig) -> None:
    homed.status(0x21, flags=0, width=10.0, speed=50.0)
    homed.g.close_session(homed.s)
    snap = homed.g.snapshot()
    assert snap.fast_stop and not snap.moving
    assert any("unannounced disconnect" in m for m in homed.g.log.messages())
    s2 = homed.g.open_session("tcp")
    assert statuses(homed.g.handle_frame(s2, Frame(0x24, b"ack"))) == [(0x24, S.E_SUCCESS)]


def test_unannounced_close_without_fast_stop_when_disabled() -> None:
    r = make_rig(settings=Settings(fast_stop_on_disconnect=False))
    r.g.close_session(r.s)
    assert not r.g.fast_stopped


def test_udp_close_never_fast_stops(rig: Rig) -> None:
    u = rig.g.open_session("udp")
    rig.g.close_session(u)
    assert not rig.g.fast_stopped


def test_final_reply_of_closed_session_is_dropped(homed: Rig) -> None:
    w = homed.g.open_session("web")
    homed.g.handle_frame(w, Frame(0x21, bytes([0]) + struct.pack("<ff", 10.0, 50.0)))
    homed.g.close_session(w)
    homed.clock.advance(10)
    assert homed.g.poll() == []


def test_deliver_callback_and_wakeup_listener(homed: Rig) -> None:
    got: list[Frame] = []
    wakes: list[int] = []
    homed.g.add_wakeup_listener(lambda: wakes.append(1))
    w = homed.g.open_session("web", deliver=got.append)
    homed.g.handle_frame(w, Frame(0x21, bytes([0]) + struct.pack("<ff", 10.0, 50.0)))
    assert wakes, "starting a motion moves next_due earlier"
    due = homed.g.next_due()
    assert due is not None and due > homed.clock.now
    homed.clock.set(due - 1e-6)
    assert homed.g.poll() == [] and got == []
    homed.clock.set(due)
    polled = homed.g.poll()
    assert [f.status for _, f in polled] == [S.E_SUCCESS] and got == [polled[0][1]]
    assert homed.g.next_due() is None


def test_queries_do_not_wake_the_runner(homed: Rig) -> None:
    wakes: list[int] = []
    homed.g.add_wakeup_listener(lambda: wakes.append(1))
    for _ in range(10):
        homed.status(0x41, flags=0, period_ms=0)
        homed.status(0x43, flags=0, period_ms=0)
    assert wakes == []


def test_pending_final_comes_before_the_next_reply_on_the_same_session(homed: Rig) -> None:
    homed.status(0x21, flags=0, width=100.0, speed=100.0)
    homed.clock.advance(5)  # motion over, nobody polled
    replies = homed.send(0x41, flags=0, period_ms=0)
    assert statuses(replies) == [(0x21, S.E_SUCCESS), (0x41, S.E_SUCCESS)]
    assert homed.g.poll() == []
