"""Hostile input benchmark: what each attack costs a `wsg sim` process, beside random bytes.

A `wsg sim` runs in its own process (TCP + UDP, no web, no serial). For each attack a separate
client sends ~1 MiB while a well-behaved UDP client of the same sim sends Loop requests back to
back. Printed per attack:

- server CPU (s) for the attack (user + system time of the sim process, per MiB sent),
- the other client's wait per request (p50 / p99 / max, ms) during the attack,
- the sim's RSS growth (MB) over the attack,
- answers the attacker received (frames).

Attacks (issue "hostile input costs bounded CPU and memory"): random bytes (the baseline); forged
1 KiB headers ``AA AA AA 99 00 04`` repeated, from the controlling client and from a refused second
client; headers with SIZE too large; complete frames with bad CRCs; valid Loop requests (legitimate
load, for scale); UDP datagrams of 65,507 bytes of forged headers; 50 requests in one datagram; and
the reply loop of ``wsg sim --count 2`` (datagrams exchanged in 1 s after one 50h).

    .venv/bin/python benchmarks/bench_abuse.py [--mib 1] [--only NAME,...]
"""

from __future__ import annotations

import argparse
import os
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Callable

import psutil
from bench_transport import free_base  # run from benchmarks/ as a script, like its siblings

from pywsg.protocol import Frame, FrameParser, Status

MIB = 1 << 20
PY = sys.executable


class Sim:
    """A `wsg sim` subprocess on fixed ports."""

    def __init__(self, count: int = 1, reply_port: int | None = None) -> None:
        self.base = free_base(2 * count + 1)
        self.tcp = self.base
        self.udp = self.base + count
        reply = 0 if reply_port is None else reply_port
        args = ["sim", "--tcp-port", str(self.tcp), "--udp-port", str(self.udp), "--udp-reply-port",
                str(reply if reply_port is not None else 0), "--serial", "off", "--web-port", "0",
                "--count", str(count), "--no-uvloop"]
        self.proc = subprocess.Popen([PY, "-c", "from pywsg.cli.main import main; main()", *args],
                                     stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
        assert self.proc.stdout is not None
        for _ in range(2 * count):
            if not self.proc.stdout.readline():
                raise RuntimeError("wsg sim did not start")
        self.ps = psutil.Process(self.proc.pid)

    def cpu(self) -> float:
        t = self.ps.cpu_times()
        return float(t.user + t.system)

    def rss(self) -> int:
        return int(self.ps.memory_info().rss)

    def close(self) -> None:
        self.proc.terminate()
        self.proc.wait(10)


class Waiter(threading.Thread):
    """The other client: UDP Loop requests back to back; records each wait (s)."""

    def __init__(self, port: int) -> None:
        super().__init__(daemon=True)
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", 0))
        self.sock.settimeout(10)
        self.port = port
        self.waits: list[float] = []
        self.lost = 0
        self.stop = threading.Event()

    def run(self) -> None:
        n = 0
        while not self.stop.is_set():
            n += 1
            req = Frame(0x06, n.to_bytes(4, "little")).encode()
            t0 = time.perf_counter()
            self.sock.sendto(req, ("127.0.0.1", self.port))
            try:
                self.sock.recvfrom(2048)
            except TimeoutError:
                self.lost += 1
                continue
            self.waits.append(time.perf_counter() - t0)
            time.sleep(0.0005)

    def finish(self) -> tuple[float, float, float]:
        self.stop.set()
        self.join(15)
        self.sock.close()
        w = sorted(self.waits) or [float("nan")]
        return w[len(w) // 2], w[min(len(w) - 1, int(len(w) * 0.99))], w[-1]


def repeat(pattern: bytes, size: int) -> bytes:
    return (pattern * (size // len(pattern) + 1))[:size]


def tcp_attack(sim: Sim, blob: bytes, second: bool = False) -> int:
    """Send ``blob`` then padding and a marker; wait for the marker's answer. Returns frames received."""
    holder = None
    if second:  # another client holds control: the attacker is a refused second client
        holder = socket.create_connection(("127.0.0.1", sim.tcp))
        holder.sendall(Frame(0x06, b"hold").encode())
        holder.recv(64)
    sock = socket.create_connection(("127.0.0.1", sim.tcp))
    marker = Frame(0x06, b"marker!").encode()
    want = (Frame.reply(0x06, Status.E_ACCESS_DENIED) if second else
            Frame.reply(0x06, Status.E_SUCCESS, b"marker!")).encode()
    got = bytearray()
    done = threading.Event()

    def read() -> None:
        while True:
            data = sock.recv(1 << 20)
            if not data:
                return
            got.extend(data)
            if got.endswith(want):
                done.set()
                return

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    sock.sendall(blob)
    sock.sendall(b"\x00" * 2100 + marker)
    if not done.wait(120):
        raise RuntimeError("the attacker's marker was never answered")
    sock.sendall(Frame(0x07).encode())
    time.sleep(0.05)
    sock.close()
    reader.join(5)
    if holder is not None:
        holder.sendall(Frame(0x07).encode())
        time.sleep(0.05)
        holder.close()
    return sum(1 for e in FrameParser().feed(bytes(got)) if isinstance(e, Frame))


def udp_attack(sim: Sim, datagrams: list[bytes]) -> int:
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.bind(("127.0.0.1", 0))
    s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4 << 20)
    got = 0
    for d in datagrams:
        s.sendto(d, ("127.0.0.1", sim.udp))
    s.settimeout(1.0)
    try:
        while True:
            s.recvfrom(65536)
            got += 1
    except TimeoutError:
        pass
    s.close()
    return got


def measure(name: str, sent: int, attack: Callable[[Sim], int]) -> None:
    """Two runs on fresh sims: CPU and RSS alone (the other client's own load would count), then
    the other client's waits while the attack runs."""
    sim = Sim()
    try:
        time.sleep(0.2)
        cpu0, rss0 = sim.cpu(), sim.rss()
        answers = attack(sim)
        cpu, rss = sim.cpu() - cpu0, sim.rss() - rss0
    finally:
        sim.close()
    sim = Sim()
    try:
        waiter = Waiter(sim.udp)
        waiter.start()
        time.sleep(0.3)
        attack(sim)
        p50, p99, worst = waiter.finish()
    finally:
        sim.close()
    print(f"{name:44s} {cpu / (sent / MIB):8.3f} {p50 * 1e3:7.2f} {p99 * 1e3:7.2f} {worst * 1e3:7.1f} "
          f"{rss / 1e6:7.1f} {answers:9d}", flush=True)


def reply_loop() -> None:
    """`wsg sim --count 2`, listen P, reply to P+1 (gripper 1's port): one 50h, count the exchange."""
    probe = free_base(3)
    sim = subprocess.Popen(
        [PY, "-c", "from pywsg.cli.main import main; main()", "sim", "--tcp-port", "0", "--udp-port", str(probe),
         "--udp-reply-port", str(probe + 1), "--serial", "off", "--web-port", "0", "--count", "2", "--no-uvloop"],
        stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    try:
        assert sim.stdout is not None
        for _ in range(2):
            sim.stdout.readline()
        ps = psutil.Process(sim.pid)
        s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        s.bind(("127.0.0.1", 0))
        t0 = ps.cpu_times()
        s.sendto(Frame(0x50).encode(), ("127.0.0.1", probe))
        time.sleep(1.0)
        t1 = ps.cpu_times()
        cpu = (t1.user + t1.system) - (t0.user + t0.system)
        print(f"{'UDP --count 2 reply loop: CPU s in 1 s':44s} {cpu:8.3f}", flush=True)
        s.close()
    finally:
        sim.terminate()
        sim.wait(10)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--mib", type=float, default=1.0, help="bytes per attack, in MiB")
    ap.add_argument("--only", default="", help="comma-separated substrings of attack names")
    args = ap.parse_args()
    size = int(args.mib * MIB)
    forged = repeat(b"\xaa\xaa\xaa\x99\x00\x04", size)
    udp_blob = repeat(b"\xaa\xaa\xaa\x99\x00\x04", 65507)
    n_dgrams = max(1, size // 65507)
    many = b"".join(Frame(0x06, bytes([i])).encode() for i in range(50))
    attacks: list[tuple[str, int, Callable[[Sim], int]]] = [
        ("random bytes (baseline)", size, lambda s: tcp_attack(s, os.urandom(size))),
        ("forged 1 KiB headers AA AA AA 99 00 04", size, lambda s: tcp_attack(s, forged)),
        ("forged headers, refused second client", size, lambda s: tcp_attack(s, forged, second=True)),
        ("SIZE too large AA AA AA 20 FF FF", size, lambda s: tcp_attack(s, repeat(b"\xaa\xaa\xaa\x20\xff\xff", size))),
        ("complete frames with bad CRCs", size,
         lambda s: tcp_attack(s, repeat(Frame(0x06, b"x").encode()[:-2] + b"\0\0", size))),
        ("valid Loop requests (legitimate load)", size,
         lambda s: tcp_attack(s, repeat(Frame(0x06, b"x").encode(), size))),
        (f"UDP: {n_dgrams} datagrams of 65,507 B forged", n_dgrams * 65507,
         lambda s: udp_attack(s, [udp_blob] * n_dgrams)),
        ("UDP: 50 requests in one datagram (x100)", 100 * len(many), lambda s: udp_attack(s, [many] * 100)),
    ]
    only = [o for o in args.only.split(",") if o]
    print(f"{'attack':44s} {'CPU s/MiB':>8s} {'p50 ms':>7s} {'p99 ms':>7s} {'max ms':>7s} {'RSS MB':>7s} "
          f"{'answers':>9s}")
    for name, sent, attack in attacks:
        if not only or any(o in name for o in only):
            measure(name, sent, attack)
    if not only or any(o in "reply loop" for o in only):
        reply_loop()


if __name__ == "__main__":
    main()
