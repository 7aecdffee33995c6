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
the reply loop of ``wsg sim --count 2`` (datagrams exchanged in 1 s after one 50h); the self-loop of
``--udp-reply-port 0`` (one datagram whose forged source is the sim's own port; forging it needs root:
skipped otherwise).

The serial rows (random bytes, bad-CRC frames, valid Loop requests) write to the pty of a
``wsg sim --serial pty`` (whole-process CPU, as above). The CAN rows run ``abuse_can.py`` in a child
process: python-can's ``virtual`` bus works only within one process, so there the sim is a thread
and its loop thread's CPU is measured (see that script).

Then the other interfaces, against one ``wsg sim --host 0.0.0.0`` with Modbus/TCP and the web
interface (so the web rules for a non-loopback bind apply; the password is read from its stderr), run
with ``ulimit -n 1024``: 1,100 idle connections each to the Modbus/TCP and web ports (connections the
sim kept, whether the command port still answers); a 128 MiB chunked body to /api/settings and 4 x
256 MiB chunked bodies to POST /login without a session (bytes the sim took, its answer, its peak RSS
growth); 1,001 cookieless GETs of /static/style.css while a user is logged in (is the user still
logged in); pipelined Modbus requests, 3 and 1,000 in one TCP write (answers received); and 1 MiB of
pipelined HTTP requests on one connection (``GET /api/world`` logged in, 404s, a bad Host header) while a
TCP client sends Loop requests (answers, sim CPU, RSS growth, the TCP client's wait); and 1 MiB of the
same requests (``GET /api/world`` logged in, 404s) over new connections of 99 requests each (under the
keep-alive budget), and of one request each (answers by status, sim CPU, the TCP client's wait).

    .venv/bin/python benchmarks/bench_abuse.py [--mib 1] [--only NAME,...] [--sim-path DIR]

``--sim-path DIR``: run the ``wsg sim`` processes from the pywsg package in DIR (e.g. an older
checkout's ``src``), to measure "before" figures with this script.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import re
import resource
import select
import socket
import struct
import subprocess
import threading
import time
from typing import Any

import psutil
from abuse_harness import (  # run from benchmarks/ as a script, like its siblings
    ENV,
    MIB,
    PY,
    SIM,
    Case,
    ProxyRun,
    Sim,
    WebSim,
    fresh,
    picked,
    run_table,
    sim_env,
    summary,
    waiting,
    waits_text,
)
from bench_transport import free_base

from pywsg.protocol import Frame, FrameParser, Status


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


def serial_attack(sim: Sim, blob: bytes) -> int:
    """Write ``blob``, padding and a marker to the sim's pty (raw mode) while another thread reads the
    answers, until the marker's. Returns frames received."""
    import tty

    fd = os.open(sim.serial, os.O_RDWR | os.O_NOCTTY)
    tty.setraw(fd)
    want = Frame.reply(0x06, Status.E_SUCCESS, b"marker!").encode()
    got = bytearray()
    done = threading.Event()

    def read() -> None:
        while not done.is_set() and select.select([fd], [], [], 30)[0]:
            got.extend(os.read(fd, 1 << 16))
            if got.endswith(want):
                done.set()

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    view = memoryview(blob + b"\x00" * 2100 + Frame(0x06, b"marker!").encode())
    while view:
        view = view[os.write(fd, view[:4096]):]
    if not done.wait(120):
        raise RuntimeError("the marker was never answered on the serial line")
    reader.join(5)
    os.close(fd)
    return sum(1 for e in FrameParser().feed(bytes(got)) if isinstance(e, Frame))


def udp_attack(sim: Sim, datagrams: list[bytes]) -> int:
    """Send ``datagrams``, each followed by a Loop probe whose answer is awaited (resent each second),
    so that none is dropped unread by a full socket buffer. Returns the answers other than the probes'."""
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.bind(("127.0.0.1", 0))
    s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4 << 20)
    s.settimeout(1.0)
    got = 0
    for i, d in enumerate(datagrams):
        s.sendto(d, ("127.0.0.1", sim.udp))
        probe = b"\xfe" + i.to_bytes(4, "little")
        answer = Frame.reply(0x06, Status.E_SUCCESS, probe).encode()
        while True:
            s.sendto(Frame(0x06, probe).encode(), ("127.0.0.1", sim.udp))
            try:
                while (data := s.recvfrom(65536)[0]) != answer:
                    got += not data.startswith(b"\xaa\xaa\xaa\x06\x07\x00\x00\x00\xfe")  # an earlier probe's
                break
            except TimeoutError:
                continue
    s.close()
    return got


def stream_row(case: Case[Sim]) -> str:
    """Two runs on fresh sims: CPU and RSS alone (the other client's own load would count), then
    the other client's waits while the attack runs."""
    serial = case.name.startswith("serial")
    with fresh(lambda: Sim(serial=serial)) as sim:
        cpu0, rss0 = sim.cpu(), sim.rss()
        answers = case.attack(sim)
        cpu, rss = sim.cpu() - cpu0, sim.rss() - rss0
    with fresh(lambda: Sim(serial=serial), settle=0) as sim, waiting(sim.udp, settle=0.3) as waiter:
        case.attack(sim)
        p50, p99, worst = waiter.finish()
    return (f"{cpu / (case.sent / MIB):8.3f} {p50 * 1e3:7.2f} {p99 * 1e3:7.2f} {worst * 1e3:7.1f} "
            f"{rss / 1e6:7.1f} {answers:9d}")


def reply_loop() -> None:
    """`wsg sim --count 2`, listen P, reply to P+1 (gripper 1's port): one 50h, count the exchange."""
    probe = free_base(3)
    sim = subprocess.Popen(
        [*SIM, "--tcp-port", "0", "--udp-port", str(probe), "--udp-reply-port", str(probe + 1), "--serial", "off",
         "--web-port", "0", "--count", "2", "--no-uvloop"],
        stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True, env=sim_env())
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


def _udp_packet(port: int, payload: bytes) -> bytes:
    """An IPv4 + UDP packet 127.0.0.1:port -> 127.0.0.1:port (UDP checksum 0: none, allowed on IPv4)."""
    udp = struct.pack(">HHHH", port, port, 8 + len(payload), 0) + payload
    lo = socket.inet_aton("127.0.0.1")
    ip = struct.pack(">BBHHHBBH4s4s", 0x45, 0, 20 + len(udp), 0, 0, 64, socket.IPPROTO_UDP, 0, lo, lo)
    return ip + udp  # the kernel fills in the IP checksum for IP_HDRINCL


def self_loop() -> None:
    """``--udp-reply-port 0``: one Loop request whose (forged) source is the sim's own UDP port."""
    name = "UDP --udp-reply-port 0 self-loop: CPU s in 1 s"
    try:
        raw = socket.socket(socket.AF_INET, socket.SOCK_RAW, socket.IPPROTO_RAW)
    except PermissionError:
        print(f"{name:44s} skipped (forging a source port needs root)", flush=True)
        return
    with contextlib.closing(raw), fresh(Sim) as sim:
        cpu0 = sim.cpu()
        raw.sendto(_udp_packet(sim.udp, Frame(0x06, b"loop").encode()), ("127.0.0.1", 0))
        time.sleep(1.0)
        print(f"{name:44s} {sim.cpu() - cpu0:8.3f}", flush=True)


# -- Modbus/TCP and the web interface ------------------------------------------------------------

def _open_now(socks: list[socket.socket]) -> int:
    n = 0
    for s in socks:
        s.setblocking(False)
        try:
            if s.recv(1) != b"":
                n += 1
        except BlockingIOError:
            n += 1
        except OSError:
            pass
    return n


def _kept(socks: list[socket.socket]) -> int:
    """Connections still open (a refused one reads EOF or a reset), once the count stops changing:
    a loaded sim may still be working through its accept queue (at most 10 s)."""
    last = -1
    for _ in range(20):
        time.sleep(0.5)
        n = _open_now(socks)
        if n == last:
            return n
        last = n
    return last


def _command_port_ms(port: int) -> str:
    """A Loop request's round trip on the command port (ms), or why it failed."""
    try:
        t0 = time.perf_counter()
        with socket.create_connection(("127.0.0.1", port), timeout=5) as s:
            s.sendall(Frame(0x06, b"ok?").encode())
            reply = s.recv(64)
            s.sendall(Frame(0x07).encode())
        return f"{(time.perf_counter() - t0) * 1e3:.1f} ms" if reply.endswith(b"ok?" + reply[-2:]) else "bad"
    except OSError as exc:
        return type(exc).__name__


def idle_flood(sim: WebSim, port: int, n: int = 1100) -> str:
    """Open ``n`` idle connections to ``port``; returns the row's figures."""
    cpu0, rss0 = sim.cpu(), sim.rss()
    socks: list[socket.socket] = []
    refused = 0
    for _ in range(n):
        try:
            socks.append(socket.create_connection(("127.0.0.1", port), timeout=2))
        except OSError:
            refused += 1
    kept = _kept(socks)
    cmd = _command_port_ms(sim.tcp)
    rss = sim.rss() - rss0
    cpu = sim.cpu() - cpu0
    for s in socks:
        s.close()
    time.sleep(0.5)
    return (f"kept {kept} of {n} (connect failed: {refused}), command port: {cmd}, "
            f"CPU {cpu:.2f} s, RSS +{rss / 1e6:.1f} MB")


def chunked(port: int, path: str, headers: dict[str, str], total: int) -> tuple[int, str]:
    """POST ``total`` bytes as a chunked body until the sim answers or stops reading (bytes sent,
    status line). Never holds more than one 64 KiB chunk."""
    chunk = b"x" * 65536
    s = socket.create_connection(("127.0.0.1", port), timeout=5)
    head = "".join(f"{k}: {v}\r\n" for k, v in headers.items())
    s.sendall(f"POST {path} HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nTransfer-Encoding: chunked\r\n{head}\r\n"
              .encode())
    sent = 0
    s.settimeout(2.0)
    try:
        while sent < total:
            if select.select([s], [], [], 0)[0]:
                break
            n = min(len(chunk), total - sent)
            s.sendall(b"%x\r\n" % n + chunk[:n] + b"\r\n")
            sent += n
        else:
            s.sendall(b"0\r\n\r\n")
    except (TimeoutError, ConnectionError):
        pass
    s.settimeout(30.0)
    answer = b""
    try:
        while b"\r\n" not in answer:
            got = s.recv(4096)
            if not got:
                break
            answer += got
    except OSError:
        pass
    finally:
        s.close()
    return sent, answer.split(b"\r\n", 1)[0].decode(errors="replace") or "(closed)"


def body_attack(sim: WebSim, path: str, headers: dict[str, str], total: int, times: int) -> str:
    sim.peak_reset()
    rss0, cpu0, t0 = sim.rss(), sim.cpu(), time.perf_counter()
    results = [chunked(sim.web, path, headers, total) for _ in range(times)]
    grown = sim.peak() - rss0
    took = max(sent for sent, _ in results)
    return (f"{results[-1][1]!r}, sim took <= {took / MIB:.1f} MiB of {total / MIB:.0f}, "
            f"peak RSS +{grown / 1e6:.0f} MB, CPU {sim.cpu() - cpu0:.2f} s, {time.perf_counter() - t0:.1f} s")


def _http(port: int, method: str, path: str, cookie: str = "", body: bytes = b"",
          ctype: str = "application/x-www-form-urlencoded",
          source: str = "127.0.0.1") -> tuple[int, dict[str, str], bytes]:
    """One HTTP/1.1 request on a new connection from ``source``: (status, headers lower-cased, body)."""
    with socket.create_connection(("127.0.0.1", port), timeout=10, source_address=(source, 0)) as s:
        extra = (f"Cookie: {cookie}\r\n" if cookie else "") + \
            (f"Content-Type: {ctype}\r\nContent-Length: {len(body)}\r\n" if method == "POST" else "")
        s.sendall(f"{method} {path} HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nConnection: close\r\n{extra}\r\n"
                  .encode() + body)
        data = b""
        while chunk := s.recv(65536):
            data += chunk
    head, _, rest = data.partition(b"\r\n\r\n")
    lines = head.decode(errors="replace").split("\r\n")
    headers: dict[str, str] = {}
    for line in lines[1:]:
        k, _, v = line.partition(":")
        if k.lower() == "set-cookie" and "wsg_session=" in v:
            headers["cookie"] = v.strip().split(";")[0]
        headers[k.lower()] = v.strip()
    return int(lines[0].split()[1]), headers, rest


def _login(sim: WebSim, source: str = "127.0.0.1") -> str:
    """Log in with the sim's password; returns the session cookie (``name=value``)."""
    _, h, page = _http(sim.web, "GET", "/login", source=source)
    cookie = h.get("cookie", "")
    m = re.search(rb'name="csrf_token" value="([^"]+)"', page)
    token = m.group(1).decode() if m else ""
    from urllib.parse import urlencode
    status, h2, _ = _http(sim.web, "POST", "/login", cookie,
                          urlencode({"csrf_token": token, "password": sim.password, "next": "/"}).encode(),
                          source=source)
    if status != 303:
        raise RuntimeError(f"login failed: HTTP {status}")
    return h2.get("cookie", cookie)


def _api_headers(sim: WebSim) -> dict[str, str]:
    """A logged-in session's cookie and CSRF token, for a JSON POST to /api."""
    cookie = _login(sim)
    _, _, body = _http(sim.web, "GET", "/api/csrf", cookie)
    m = re.search(rb'"token"\s*:\s*"([^"]+)"', body)
    return {"Cookie": cookie, "X-CSRF-Token": m.group(1).decode() if m else "",
            "Content-Type": "application/json"}


def session_flood(sim: WebSim, n: int = 1001) -> str:
    """The user on 127.0.0.2, the flood from 127.0.0.1: another address, as it would be (the
    per-client rate limit answers most of the flood 429 since pywsg 0.3.0)."""
    user = "127.0.0.2"
    cookie = _login(sim, user)
    before = _http(sim.web, "GET", "/api/state", cookie, source=user)[0]
    t0 = time.perf_counter()
    flood: dict[int, int] = {}
    for _ in range(n):
        status = _http(sim.web, "GET", "/static/style.css")[0]
        flood[status] = flood.get(status, 0) + 1
    dt = time.perf_counter() - t0
    after = _http(sim.web, "GET", "/api/state", cookie, source=user)[0]
    answers = ", ".join(f"{v} x {k}" for k, v in sorted(flood.items()))
    return (f"GET /api/state with the login cookie: {before} before, {after} after "
            f"({'still logged in' if after == 200 else 'logged out'}); {n} GETs in {dt:.1f} s ({answers})")


def modbus_pipelined(sim: WebSim, n: int) -> str:
    """``n`` FC3 requests (read 4 holding registers) in one TCP write: answers received in 2 s."""
    data = b"".join(struct.pack(">HHHBBHH", i & 0xFFFF, 0, 6, 1, 3, 0, 4) for i in range(n))
    cpu0, t0 = sim.cpu(), time.perf_counter()
    got = b""
    with socket.create_connection(("127.0.0.1", sim.modbus), timeout=2) as s:
        s.sendall(data)
        try:
            while len(got) < 17 * n:  # 7 bytes MBAP + FC, count, 8 data bytes
                chunk = s.recv(65536)
                if not chunk:
                    break
                got += chunk
        except TimeoutError:
            pass
    dt = time.perf_counter() - t0
    return f"{len(got) // 17} of {n} answered, {dt * 1e3:.0f} ms, CPU {sim.cpu() - cpu0:.2f} s"


def web_pipelined(sim: WebSim, path: str, host: str = "", login: bool = True) -> str:
    """1 MiB of ``GET path`` pipelined on one connection (``host``: the Host header, default the
    sim's own), while a TCP client sends Loop requests: answers, sim CPU, RSS growth, the other's wait."""
    cookie = f"Cookie: {_login(sim)}\r\n" if login else ""
    one = f"GET {path} HTTP/1.1\r\nHost: {host or f'127.0.0.1:{sim.web}'}\r\n{cookie}\r\n".encode()
    blob = one * (MIB // len(one))
    with waiting(sim.tcp, tcp=True) as waiter:
        rss0, cpu0, t0 = sim.rss(), sim.cpu(), time.perf_counter()
        sim.peak_reset()
        got = 0
        with socket.create_connection(("127.0.0.1", sim.web), timeout=120) as s:
            def send() -> None:
                with contextlib.suppress(OSError):  # the sim closes the connection once it is done
                    s.sendall(blob)

            threading.Thread(target=send, daemon=True).start()
            with contextlib.suppress(OSError):
                while chunk := s.recv(65536):
                    got += chunk.count(b"HTTP/1.1 ")  # a status line split across reads is missed: rare
        dt = time.perf_counter() - t0
        cpu = sim.cpu() - cpu0
        grown = (sim.peak() - rss0) / 1e6
        waiter.finish()
    return (f"{got} of {len(blob) // len(one)} answered in {dt:.1f} s, CPU {cpu:.2f} s, RSS +{grown:.1f} MB, "
            f"{waits_text(summary(waiter.waits, 0.0))}")


def web_many_connections(sim: WebSim, path: str, per_connection: int = 99) -> str:
    """1 MiB of ``GET path`` (logged in: the web password as a Bearer token for /api/world, the
    scripts' API, a login cookie otherwise) over new connections of ``per_connection`` pipelined
    requests each, the last asking to close (under the keep-alive budget of 100), while a TCP client
    sends Loop requests: answers by status, sim CPU, the other client's wait."""
    auth = (f"Authorization: Bearer {sim.password}" if path.startswith("/api/world")
            else f"Cookie: {_login(sim)}")
    one = f"GET {path} HTTP/1.1\r\nHost: 127.0.0.1:{sim.web}\r\n{auth}\r\n\r\n".encode()
    last = one.replace(b"\r\n\r\n", b"\r\nConnection: close\r\n\r\n")
    total = MIB // len(one)
    statuses: dict[bytes, int] = {}
    with waiting(sim.tcp, tcp=True) as waiter:
        cpu0, t0 = sim.cpu(), time.perf_counter()
        for i in range(0, total, per_connection):
            n = min(per_connection, total - i)
            got = b""
            with socket.create_connection(("127.0.0.1", sim.web), timeout=60) as s, contextlib.suppress(OSError):
                s.sendall(one * (n - 1) + last)
                while chunk := s.recv(65536):
                    got += chunk
            for code in re.findall(rb"HTTP/1\.1 (\d{3}) ", got):
                statuses[code] = statuses.get(code, 0) + 1
        dt = time.perf_counter() - t0
        cpu = sim.cpu() - cpu0
        waiter.finish()
    answers = ", ".join(f"{v} x {k.decode()}" for k, v in sorted(statuses.items()))
    return (f"{total} requests on {-(-total // per_connection)} connections: {answers}; {dt:.1f} s, "
            f"CPU {cpu:.2f} s, {waits_text(summary(waiter.waits, 0.0))}")


INTERFACE_CASES: list[Case[WebSim]] = [
    Case("Modbus/TCP: 1,100 idle connections", lambda s: idle_flood(s, s.modbus)),
    Case("web: 1,100 idle connections", lambda s: idle_flood(s, s.web)),
    Case("web: 128 MiB chunked to /api/settings", lambda s: body_attack(
        s, "/api/settings", _api_headers(s), 128 * MIB, 1)),
    Case("web: 4 x 256 MiB chunked to POST /login", lambda s: body_attack(
        s, "/login", {"Content-Type": "application/x-www-form-urlencoded"}, 256 * MIB, 4)),
    Case("web: 1,001 cookieless GETs, user logged in", session_flood),
    Case("Modbus/TCP: 3 requests in one write", lambda s: modbus_pipelined(s, 3)),
    Case("Modbus/TCP: 1,000 requests in one write", lambda s: modbus_pipelined(s, 1000)),
    Case("Modbus/TCP: 6,000 requests in one write", lambda s: modbus_pipelined(s, 6000)),
    Case("Modbus/TCP: 1 MiB of requests in one write", lambda s: modbus_pipelined(s, MIB // 12)),
    Case("web: 1 MiB pipelined GET /api/world", lambda s: web_pipelined(s, "/api/world")),
    Case("web: 1 MiB pipelined 404s", lambda s: web_pipelined(s, "/no/such/page")),
    Case("web: 1 MiB pipelined, bad Host", lambda s: web_pipelined(s, "/api/world", host="evil.example")),
    Case("web: 1 MiB over connections of 99, GET /api/world", lambda s: web_many_connections(s, "/api/world")),
    Case("web: 1 MiB over connections of 99, 404s", lambda s: web_many_connections(s, "/no/such/page")),
    Case("web: 1 MiB, one request per connection, 404s", lambda s: web_many_connections(s, "/no/such/page", 1)),
]


def interface_row(case: Case[WebSim]) -> str:
    """A Modbus/TCP or web row: one sim each, so one attack cannot spoil the next."""
    with fresh(WebSim, settle=0.3) as sim:
        try:
            result = case.attack(sim)
        except Exception as exc:  # a figure for the table, not a traceback
            result = f"failed: {type(exc).__name__}: {exc}"
        alive = "sim alive" if sim.proc.poll() is None else f"sim exited {sim.proc.returncode}"
    return f"{result}; {alive}"


def interfaces(only: list[str]) -> None:
    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    resource.setrlimit(resource.RLIMIT_NOFILE, (max(soft, min(hard, 8192)), hard))  # our own 2,200 sockets
    run_table(INTERFACE_CASES, only, interface_row)


def _proxy_run(blob: bytes, with_waiter: bool, pcap: bool) -> tuple[float, int, int, tuple[float, float, float]]:
    """One fresh sim and proxy: send ``blob``; (proxy CPU s, peak RSS growth, log bytes, waits)."""
    import tempfile

    with fresh(Sim, settle=0) as sim, tempfile.TemporaryDirectory() as tmp, \
            fresh(lambda: ProxyRun(sim, tmp, pcap), settle=0) as px:
        with contextlib.ExitStack() as stack:
            waiter = stack.enter_context(waiting(px.port, tcp=True, settle=0)) if with_waiter else None
            time.sleep(0.3)
            cpu0, rss0 = px.cpu(), px.rss()
            px.peak_reset()
            s = socket.create_connection(("127.0.0.1", px.port))
            # the waiter holds control when it runs: then 07h is answered E_ACCESS_DENIED
            byes = (Frame.reply(0x07, Status.E_SUCCESS).encode(),
                    Frame.reply(0x07, Status.E_ACCESS_DENIED).encode())
            tail = bytearray()

            def drain() -> None:
                with contextlib.suppress(OSError):  # the proxy before item 1 reset the connection
                    while not tail.endswith(byes) and (data := s.recv(1 << 16)):
                        tail[:] = tail[-64:] + data

            reader = threading.Thread(target=drain, daemon=True)
            reader.start()
            s.sendall(blob)
            s.sendall(b"\x00" * 2100 + Frame(0x07).encode())
            reader.join(120)
            s.close()
            waits = waiter.finish() if waiter is not None else (0.0, 0.0, 0.0)
        time.sleep(1.5)  # the proxy's decoding catches up
        return px.cpu() - cpu0, px.peak() - rss0, px.log_bytes(), waits


def proxy_row(case: Case[bytes]) -> str:
    """``blob`` through `wsg proxy` (text log, --jsonl, --pcap) to a sim: the proxy's CPU, its log
    bytes per byte sent and its peak RSS growth alone; then the wait of another client of the same
    proxy while it runs."""
    blob, pcap = case.extra
    cpu, rss, logged, _ = _proxy_run(blob, False, pcap)
    _, _, _, (p50, p99, worst) = _proxy_run(blob, True, pcap)
    return (f"{cpu / (len(blob) / MIB):8.3f} {p50 * 1e3:7.2f} {p99 * 1e3:7.2f} {worst * 1e3:7.1f} "
            f"{rss / 1e6:7.1f} {logged / len(blob):8.1f}x")


def random_crcs(size: int) -> bytes:
    """8-byte 50h frames with random checksums (each frame different; a few hold AAh in the CRC)."""
    head = Frame(0x50).encode()[:-2]
    rnd = os.urandom(size // 4)
    return b"".join(head + rnd[i : i + 2] for i in range(0, size // 4, 2))[:size]


def proxy_cases(size: int, only: list[str]) -> None:
    blobs: list[tuple[str, bytes, bool]] = [
        ("proxy: random bytes (baseline)", os.urandom(size), False),
        ("proxy: 8-byte frames with bad CRCs", repeat(Frame(0x50).encode()[:-2] + b"\0\0", size), False),
        ("proxy: valid 50h requests", repeat(Frame(0x50).encode(), size), False),
        ("proxy: valid Loop requests (06h, 1 byte)", repeat(Frame(0x06, b"x").encode(), size), False),
        ("proxy: 8-byte frames, random CRCs", random_crcs(size), False),
        ("proxy: Loop requests holding AA AA AA AA", repeat(Frame(0x06, b"\xaa" * 4).encode(), size), False),
        ("proxy --pcap: 70,000 zero bytes then 06h", b"\0" * 70_000 + Frame(0x06, b"x").encode(), True),
        ("proxy --pcap: 8-byte frames with bad CRCs", repeat(Frame(0x50).encode()[:-2] + b"\0\0", size), True),
    ]
    cases: list[Case[Any]] = [Case(name, lambda _: None, len(blob), (blob, pcap)) for name, blob, pcap in blobs]
    run_table(cases, only, proxy_row, f"{'proxy (text log, --jsonl)':44s} {'CPU s/MiB':>8s} {'p50 ms':>7s} "
              f"{'p99 ms':>7s} {'max ms':>7s} {'RSS MB':>7s} {'log/sent':>9s}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--mib", type=float, default=1.0, help="bytes per attack, in MiB")
    ap.add_argument("--only", default="", help="comma-separated substrings of attack names")
    ap.add_argument("--sim-path", default="", help="run wsg sim from the pywsg package in this directory")
    args = ap.parse_args()
    if args.sim_path:
        ENV["sim"] = {**os.environ, "PYTHONPATH": os.path.abspath(args.sim_path)}
    size = int(args.mib * MIB)
    forged = repeat(b"\xaa\xaa\xaa\x99\x00\x04", size)
    udp_blob = repeat(b"\xaa\xaa\xaa\x99\x00\x04", 65507)
    n_dgrams = max(1, size // 65507)
    many = b"".join(Frame(0x06, bytes([i])).encode() for i in range(50))
    bad_crc = repeat(Frame(0x06, b"x").encode()[:-2] + b"\0\0", size)
    loops = repeat(Frame(0x06, b"x").encode(), size)
    attacks: list[Case[Sim]] = [
        Case("random bytes (baseline)", lambda s: tcp_attack(s, os.urandom(size)), size),
        Case("forged 1 KiB headers AA AA AA 99 00 04", lambda s: tcp_attack(s, forged), size),
        Case("forged headers, refused second client", lambda s: tcp_attack(s, forged, second=True), size),
        Case("SIZE too large AA AA AA 20 FF FF", lambda s: tcp_attack(s, repeat(b"\xaa\xaa\xaa\x20\xff\xff", size)),
             size),
        Case("complete frames with bad CRCs", lambda s: tcp_attack(s, bad_crc), size),
        Case("valid Loop requests (legitimate load)", lambda s: tcp_attack(s, loops), size),
        Case("valid 50h requests (8 bytes each)", lambda s: tcp_attack(s, repeat(Frame(0x50).encode(), size)), size),
        Case(f"UDP: {n_dgrams} datagrams of 65,507 B forged", lambda s: udp_attack(s, [udp_blob] * n_dgrams),
             n_dgrams * 65507),
        Case("UDP: 50 requests in one datagram (x100)", lambda s: udp_attack(s, [many] * 100), 100 * len(many)),
        Case("serial (pty): random bytes (baseline)", lambda s: serial_attack(s, os.urandom(size)), size),
        Case("serial (pty): complete frames with bad CRCs", lambda s: serial_attack(s, bad_crc), size),
        Case("serial (pty): valid Loop requests", lambda s: serial_attack(s, loops), size),
    ]
    only = [o for o in args.only.split(",") if o]
    run_table(attacks, only, stream_row, f"{'attack':44s} {'CPU s/MiB':>8s} {'p50 ms':>7s} {'p99 ms':>7s} "
              f"{'max ms':>7s} {'RSS MB':>7s} {'answers':>9s}")
    if picked("CAN (virtual bus)", only):  # in-process: a child of its own
        subprocess.run([PY, os.path.join(os.path.dirname(os.path.abspath(__file__)), "abuse_can.py"),
                        "--mib", str(args.mib)], env=sim_env(), check=False)
    if picked("reply loop", only):
        reply_loop()
    if picked("self-loop", only):
        self_loop()
    interfaces(only)
    proxy_cases(size, only)


if __name__ == "__main__":
    main()
