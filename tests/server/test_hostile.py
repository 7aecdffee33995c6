"""Hostile input (issue 13, items 1-3): each attack sent exactly, its cost compared with random bytes
measured in the same test (server CPU from the loop thread's clock, other clients' waits).

Targets: any 1 MiB costs at most ~0.5 s of server CPU, and a UDP client of the same process never
waits more than ~50 ms. Bounds are asserted as "target + a multiple of the random-bytes baseline" so a
loaded 2-core machine does not fail them; the defects they guard against cost 10x more.
"""

from __future__ import annotations

import gc
import os
import socket
import struct
import threading
import time
from collections.abc import Callable

import pytest

from pywsg.protocol import CATALOG, Frame, FrameParser, Status

from .conftest import SimThread, TcpClient, UdpClient, bad_crc, loop_frame

MIB = 1 << 20


def repeated(pattern: bytes, size: int = MIB) -> bytes:
    return (pattern * (size // len(pattern) + 1))[:size]


FORGED_1K = repeated(bytes.fromhex("AAAAAA990004"))  # each header announces 1 KiB: a CRC per candidate
FORGED_HUGE = repeated(bytes.fromhex("AAAAAA99FFFF"))  # each header announces 64 KiB: an error per header


class Pinger(threading.Thread):
    """A UDP client of the same process sending Loop requests back to back; records each wait (s)."""

    def __init__(self, port: int) -> None:
        super().__init__(daemon=True)
        self.client = UdpClient(port)
        self.waits: list[float] = []
        self.lost = 0
        self._stop_evt = threading.Event()

    def run(self) -> None:
        n = 0
        while not self._stop_evt.is_set():
            n += 1
            data = n.to_bytes(4, "little")
            t0 = time.perf_counter()
            self.client.send(loop_frame(data))
            try:
                while True:
                    f = self.client.receive(timeout=10)
                    if f.command_id == 0x06 and f.params == data:
                        break
            except TimeoutError:
                self.lost += 1
            self.waits.append(time.perf_counter() - t0)
            time.sleep(0.002)

    def stop(self) -> list[float]:
        self._stop_evt.set()
        self.join(15)
        self.client.close()
        return sorted(self.waits)


def server_cpu(sim: SimThread) -> float:
    """CPU seconds of the server's loop thread (the sim runs on its own thread)."""
    return float(sim.call(time.thread_time))


def reader_until(sock: socket.socket, command_id: int) -> threading.Event:
    """Read what the server answers; the event is set when a reply to ``command_id`` arrives."""
    seen = threading.Event()

    def run() -> None:
        parser = FrameParser()
        try:
            while data := sock.recv(1 << 16):
                for f in parser.feed(data):
                    if isinstance(f, Frame) and f.command_id == command_id:
                        seen.set()
        except OSError:
            pass

    threading.Thread(target=run, daemon=True).start()
    return seen


def attack_tcp(sim: SimThread, blob: bytes, refused: bool = False) -> tuple[float, list[float]]:
    """Send ``blob`` on one TCP connection (a second, refused one if ``refused``), wait until the
    server has worked through it; return (server CPU s, sorted waits of a concurrent UDP client)."""
    holder = TcpClient(sim.g.tcp_port) if refused else None
    if holder is not None:
        assert holder.request(0x06, b"mine").status == Status.E_SUCCESS
    # the test process holds far more objects than a server: keep the collector's full passes over
    # them (tens of ms, a pause for every thread) out of the measurement
    gc.collect()
    gc.freeze()
    pinger = Pinger(sim.g.udp_port)
    pinger.start()
    time.sleep(0.05)
    cpu0 = server_cpu(sim)
    c = TcpClient(sim.g.tcp_port)
    c.sock.settimeout(60)
    done = reader_until(c.sock, 0x06)  # the blobs hold no valid frame
    for i in range(0, len(blob), 65536):
        c.sock.sendall(blob[i : i + 65536])
    # zero bytes resolve any header still waiting for its SIZE; the Loop answer (in order) then
    # proves the server got through the blob
    c.sock.sendall(b"\x00" * 1040 + loop_frame(b"end-of-attack"))
    assert done.wait(60), "no answer after the attack"
    time.sleep(0.05)
    cpu = server_cpu(sim) - cpu0
    waits = pinger.stop()
    gc.unfreeze()
    assert pinger.lost == 0, f"the UDP client lost {pinger.lost} answers"
    c.sock.shutdown(socket.SHUT_RDWR)  # wakes the reader thread
    c.close()
    if holder is not None:
        holder.request(0x07)
        holder.close()
    return cpu, waits


def p99(waits: list[float]) -> float:
    return waits[min(len(waits) - 1, int(len(waits) * 0.99))]


def check_bounded(base: tuple[float, list[float]], attack: tuple[float, list[float]], what: str) -> None:
    base_cpu, base_waits = base
    cpu, waits = attack
    assert len(waits) >= 5, f"{what}: the UDP client got only {len(waits)} answers"
    assert cpu <= 0.5 + 2 * base_cpu, f"{what}: {cpu:.2f} s CPU per MiB (random bytes: {base_cpu:.2f} s)"
    # 50 ms is the target (docs/benchmarks.md, measured with the server in its own process); here the
    # client threads share the server's process (GIL, garbage collector) on a loaded machine
    assert p99(waits) <= 0.1 + 3 * p99(base_waits), (
        f"{what}: other client waited p99 {p99(waits) * 1e3:.0f} ms (random: {p99(base_waits) * 1e3:.0f} ms)")
    assert waits[-1] <= 0.3 + 3 * base_waits[-1], f"{what}: other client waited {waits[-1]:.2f} s"


@pytest.fixture
def hostile(sim_factory: Callable[..., SimThread]) -> SimThread:
    return sim_factory(tcp_port=0, udp_port=0)


def test_forged_1kib_headers_cost_what_random_bytes_cost(hostile: SimThread) -> None:
    """Item 1: 1 MiB of ``AA AA AA 99 00 04`` (command manual 1.2.1 frame, SIZE 1024, wrong CRC)."""
    base = attack_tcp(hostile, os.urandom(MIB))
    check_bounded(base, attack_tcp(hostile, FORGED_1K), "AA AA AA 99 00 04")


def test_forged_headers_from_a_refused_second_client(hostile: SimThread) -> None:
    base = attack_tcp(hostile, os.urandom(MIB), refused=True)
    check_bounded(base, attack_tcp(hostile, FORGED_1K, refused=True), "refused client")


def test_oversized_headers_get_one_error_per_maximal_frame(hostile: SimThread) -> None:
    base = attack_tcp(hostile, os.urandom(MIB))
    check_bounded(base, attack_tcp(hostile, FORGED_HUGE), "AA AA AA 99 FF FF")


def test_error_answers_are_one_per_span_not_per_candidate(hostile: SimThread) -> None:
    """64 KiB of overlapping forged headers: about one E_CHECKSUM_ERROR per 1 KiB, not 10,000."""
    c = TcpClient(hostile.g.tcp_port)
    c.sock.sendall(FORGED_1K[: 1 << 16] + b"\x00" * 1040)
    c.send(loop_frame(b"after"))
    errors = 0
    while True:
        f = c.receive(timeout=10)
        if f.command_id == 0x06:
            assert f.params == b"after"
            break
        assert f.command_id == 0x99 and f.status == Status.E_CHECKSUM_ERROR
        errors += 1
    assert 1 <= errors <= (1 << 16) // 1024 + 2
    # frames that do not overlap still get one answer each (the manual: an answer per frame)
    for i in range(20):
        c.send(bad_crc(loop_frame(bytes([i + 1]) * 3)))
    assert [c.reply(0x06).status for _ in range(20)] == [Status.E_CHECKSUM_ERROR] * 20
    c.close()


# -- UDP: one frame per datagram, no reply loops ------------------------------------------------


def collect(sock: socket.socket, quiet: float = 0.3) -> list[bytes]:
    sock.settimeout(quiet)
    got = []
    try:
        while True:
            got.append(sock.recvfrom(65536)[0])
    except TimeoutError:
        pass
    return got


def test_udp_datagram_of_many_frames_gets_one_answer(hostile: SimThread) -> None:
    """Item 3: 50 requests in one 400-byte datagram, and 65,507 bytes of forged headers."""
    u = UdpClient(hostile.g.udp_port)
    u.send(b"".join(Frame(0x06, b"ab").encode() for _ in range(40)))  # 40 x 10 bytes
    replies = collect(u.sock)
    assert len(replies) == 1
    assert Frame(0x06, struct.pack("<H", Status.E_SUCCESS) + b"ab").encode() == replies[0]
    u.send(repeated(bytes.fromhex("AAAAAA990004"), 65507))
    assert len(collect(u.sock)) <= 1
    u.send(repeated(bytes.fromhex("AAAAAA99FFFF"), 65507))
    assert len(collect(u.sock)) <= 1
    assert u.request(0x06, b"still").params == b"still"
    u.close()


def _free_udp_pair() -> int:
    """A port P with P and P+1 free on 127.0.0.1."""
    for _ in range(50):
        a = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        a.bind(("127.0.0.1", 0))
        p = a.getsockname()[1]
        b = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            b.bind(("127.0.0.1", p + 1))
        except OSError:
            continue
        finally:
            a.close()
            b.close()
        return int(p)
    raise RuntimeError("no two consecutive free UDP ports")


def test_two_grippers_do_not_ping_pong(sim_factory: Callable[..., SimThread]) -> None:
    """Item 2: ``--count 2``, gripper 0 on P replies to P+1, where gripper 1 listens."""
    port = _free_udp_pair()
    sim = sim_factory(tcp_port=None, udp_port=port, udp_reply_port=port + 1, count=2)
    client = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    client.bind(("127.0.0.1", 0))
    client.sendto(Frame(0x50).encode(), ("127.0.0.1", port))
    time.sleep(0.5)
    counts = sim.call(lambda: [g.udp.datagrams for g in sim.sim.grippers])
    assert counts == [1, 0], counts  # gripper 0 sent nothing to its sibling
    assert sim.call(lambda: sim.sim.grippers[0].udp.looped) == 1
    client.close()


def _spoofed(src: tuple[str, int], dst: tuple[str, int], payload: bytes) -> bool:
    """Send a UDP datagram with a forged source address (raw socket: needs root). False if not allowed."""
    try:
        raw = socket.socket(socket.AF_INET, socket.SOCK_RAW, socket.IPPROTO_RAW)
    except PermissionError:
        return False
    udp = struct.pack("!HHHH", src[1], dst[1], 8 + len(payload), 0) + payload  # checksum 0: none
    ip = struct.pack("!BBHHHBBH4s4s", 0x45, 0, 20 + len(udp), 0, 0, 64, socket.IPPROTO_UDP, 0,
                     socket.inet_aton(src[0]), socket.inet_aton(dst[0]))
    raw.sendto(ip + udp, dst)
    raw.close()
    return True


def test_udp_reply_to_sender_port_never_answers_itself(sim_factory: Callable[..., SimThread]) -> None:
    """Item 2: ``--udp-reply-port 0``; one datagram whose source is the server's own port."""
    sim = sim_factory(tcp_port=None, udp_port=0, udp_reply_port=None)
    me = ("127.0.0.1", sim.g.udp_port)
    frame = Frame(0x06, b"loop?").encode()
    if not _spoofed(me, me, frame):  # not root: deliver the same datagram the kernel would
        sim.call(lambda: sim.g.udp.datagram_received(frame, me))
    time.sleep(0.5)
    assert sim.call(lambda: sim.g.udp.datagrams) == 1
    assert sim.call(lambda: sim.g.udp.looped) == 1
    u = UdpClient(sim.g.udp_port)
    assert u.request(0x06, b"ok").params == b"ok"
    u.close()


def test_cpu_of_udp_forged_datagrams_is_bounded(hostile: SimThread) -> None:
    """Per datagram the server reads one frame: 16 x 64 KiB of forged headers cost little CPU."""
    u = UdpClient(hostile.g.udp_port)

    def blast(blob: bytes) -> float:
        cpu0 = server_cpu(hostile)
        for i in range(0, len(blob), 65507):
            u.send(blob[i : i + 65507])
            time.sleep(0.002)
        u.send(loop_frame(b"sync"))
        while u.receive(timeout=10).command_id != 0x06:  # error answers to the blob come first
            pass
        return server_cpu(hostile) - cpu0

    base = blast(os.urandom(MIB))
    cpu = blast(FORGED_1K)
    assert cpu <= 0.2 + 2 * base, f"{cpu:.2f} s for 1 MiB of forged headers over UDP (random: {base:.2f} s)"
    u.close()


def test_state_reads_are_unaffected_by_the_attack(hostile: SimThread) -> None:
    """After the worst input the device still answers correctly (nothing leaked into its state)."""
    attack_tcp(hostile, FORGED_1K[: MIB // 4])
    u = UdpClient(hostile.g.udp_port)
    state = u.request(0x40, CATALOG[0x40].encode_request(flags=0, period_ms=0))
    assert state.status == Status.E_SUCCESS
    u.close()
