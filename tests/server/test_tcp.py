"""TCP command interface over real sockets on 127.0.0.1."""

from __future__ import annotations

import itertools
import socket
import struct
import threading
import time
from typing import Any

from pywsg.protocol import CATALOG, Frame, Status, SystemFlag

from .conftest import AUTO_IDS, SimThread, TcpClient, exercise_catalog, sample_request


def system_state(client: Any) -> SystemFlag:
    r = client.request(0x40, CATALOG[0x40].encode_request(flags=0, period_ms=0))
    assert r.status == Status.E_SUCCESS
    return SystemFlag(struct.unpack("<I", r.params)[0])


def wait_for(pred: Any, timeout: float = 3.0) -> None:
    deadline = time.monotonic() + timeout
    while not pred():
        assert time.monotonic() < deadline, "condition not reached"
        time.sleep(0.005)


def controller_free(sim: SimThread) -> bool:
    return bool(sim.call(lambda: sim.g.tcp.controller is None))


def test_every_catalog_command_answered_over_tcp(sim: SimThread) -> None:
    c = TcpClient(sim.g.tcp_port)
    seen = exercise_catalog(c.request, lambda cid: c.reply(cid, timeout=10, skip=AUTO_IDS))
    assert set(seen) == set(CATALOG)
    c.request(0x07)
    c.close()


def test_unknown_command_and_bad_crc_get_the_spec_status(sim: SimThread) -> None:
    c = TcpClient(sim.g.tcp_port)
    assert c.request(0x90).status == Status.E_CMD_UNKNOWN
    frame = Frame(0x06, b"abc").encode()
    c.send(frame[:-2] + bytes([frame[-2] ^ 0xFF, frame[-1]]))
    assert c.reply(0x06).status == Status.E_CHECKSUM_ERROR
    c.send(b"\xaa\xaa\xaa\x06\xff\xff")  # forged SIZE 65535: answered at once, not waited for
    assert c.reply(0x06, timeout=2).status == Status.E_CMD_FORMAT_ERROR
    assert c.request(0x06, b"ok").params == b"ok"
    c.close()


def test_unannounced_disconnect_raises_fast_stop(sim: SimThread) -> None:
    c = TcpClient(sim.g.tcp_port)
    assert not system_state(c) & SystemFlag.SF_FAST_STOP
    c.close()  # no 07h
    wait_for(lambda: controller_free(sim))
    c2 = TcpClient(sim.g.tcp_port)
    assert system_state(c2) & SystemFlag.SF_FAST_STOP
    c2.request(0x07)
    c2.close()


def test_announced_disconnect_does_not_fast_stop(sim: SimThread) -> None:
    c = TcpClient(sim.g.tcp_port)
    assert c.request(0x07).status == Status.E_SUCCESS
    assert c.request(0x06, b"x").status == Status.E_ACCESS_DENIED  # after 07h on this connection
    c.close()
    wait_for(lambda: controller_free(sim))
    c2 = TcpClient(sim.g.tcp_port)
    assert c2.request(0x06, b"x").status == Status.E_SUCCESS  # the next connection starts fresh
    assert not system_state(c2) & SystemFlag.SF_FAST_STOP
    c2.request(0x07)
    c2.close()


def test_fast_stop_on_disconnect_setting_off(sim: SimThread) -> None:
    g = sim.g.gripper
    sim.call(lambda: g.apply_settings(g.settings.updated(fast_stop_on_disconnect=False)))
    c = TcpClient(sim.g.tcp_port)
    c.request(0x06, b"x")
    c.close()
    wait_for(lambda: controller_free(sim))
    c2 = TcpClient(sim.g.tcp_port)
    assert not system_state(c2) & SystemFlag.SF_FAST_STOP
    c2.close()


def test_second_client_is_refused_and_first_keeps_control(sim: SimThread) -> None:
    first = TcpClient(sim.g.tcp_port)
    assert first.request(0x06, b"1").status == Status.E_SUCCESS
    second = TcpClient(sim.g.tcp_port)
    for cid in (0x06, 0x21, 0x23, 0x40):
        assert second.request(cid, sample_request(cid)).status == Status.E_ACCESS_DENIED
    second.close()
    # the refused client's close is no unannounced disconnect of the controller: no FAST STOP
    assert not system_state(first) & SystemFlag.SF_FAST_STOP
    assert first.request(0x06, b"still mine").params == b"still mine"
    first.request(0x07)
    first.close()


def test_motion_pending_then_final_and_socket_options(sim: SimThread) -> None:
    c = TcpClient(sim.g.tcp_port)
    c.request(0x20, sample_request(0x20))  # homing (pending) ...
    c.reply(0x20, timeout=10, skip=AUTO_IDS)  # ... then its final frame
    r = c.request(0x21, CATALOG[0x21].encode_request(flags=0, width=30.0, speed=200.0))
    assert r.status == Status.E_CMD_PENDING
    final = c.reply(0x21, timeout=10)
    assert final.status == Status.E_SUCCESS
    server_sock = sim.call(lambda: next(iter(sim.g.tcp.connections)).transport.get_extra_info("socket"))
    assert server_sock.getsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY)
    assert server_sock.getsockopt(socket.SOL_SOCKET, socket.SO_KEEPALIVE)
    c.request(0x07)
    c.close()


class SleeperThread(threading.Thread):
    """``time.sleep(0.010)`` in a loop; :meth:`stop` returns the median period it achieved (s)."""

    def __init__(self) -> None:
        super().__init__(daemon=True)
        self.stamps: list[float] = []
        self.done = threading.Event()

    def run(self) -> None:
        while not self.done.is_set():
            time.sleep(0.010)
            self.stamps.append(time.monotonic())

    def stop(self) -> float:
        self.done.set()
        self.join(30)
        gaps = sorted(b - a for a, b in itertools.pairwise(self.stamps))
        return gaps[len(gaps) // 2] if gaps else 0.010


def test_auto_update_every_10ms_and_unsubscribe(sim: SimThread) -> None:
    c = TcpClient(sim.g.tcp_port)
    spec = CATALOG[0x43]
    assert c.request(0x43, spec.encode_request(flags=1, period_ms=10)).status == Status.E_SUCCESS
    times = []
    ref = SleeperThread()  # the baseline: 10 ms sleeps in a thread of this process, at the same time
    ref.start()
    for _ in range(30):
        f = c.receive()
        assert f.command_id == 0x43 and f.status == Status.E_SUCCESS
        times.append(time.monotonic())
    ref_median = ref.stop()
    gaps = sorted(b - a for a, b in itertools.pairwise(times))
    # median period ~10 ms: never faster; slower only as far as a thread sleeping 10 ms is (a loaded machine)
    assert 0.007 < gaps[len(gaps) // 2] < max(0.013, 1.3 * ref_median), (gaps[len(gaps) // 2], ref_median)
    c.send(Frame(0x43, spec.encode_request(flags=0, period_ms=10)).encode())
    time.sleep(0.05)
    c.sock.settimeout(0.05)
    try:
        while c.sock.recv(65536):
            pass
    except TimeoutError:
        pass
    c.sock.settimeout(0.15)
    try:
        late = c.sock.recv(100)
    except TimeoutError:
        late = b""
    assert late == b"", "auto-update packets after unsubscribing"
    c.close()
