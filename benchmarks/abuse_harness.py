"""The harness of ``bench_abuse.py``: a measured process (``wsg sim``, ``wsg proxy``), the other client
whose waits are recorded while an attack runs, and one loop that runs a table of cases, each on a
fresh process, printing one row per case. The attacks themselves and the tables are in
``bench_abuse.py``; a case is data: a name, the bytes it sends, the attack, how to measure it.
"""

from __future__ import annotations

import os
import resource
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any, Generic, TypeVar

import psutil
from bench_transport import free_base  # run from benchmarks/ as a script, like its siblings

from pywsg.protocol import Frame, FrameParser

MIB = 1 << 20
PY = sys.executable
SIM = [PY, "-c", "from pywsg.cli.main import main; main()", "sim"]
ENV: dict[str, dict[str, str] | None] = {"sim": None}  # --sim-path: the environment of every wsg process


def sim_env() -> dict[str, str] | None:
    return ENV["sim"]


# ---------------------------------------------------------------- measured processes
class Measured:
    """A child process whose CPU (user + system s), RSS and peak RSS (bytes) are read."""

    proc: subprocess.Popen[str]
    ps: psutil.Process

    def _watch(self) -> None:
        self.ps = psutil.Process(self.proc.pid)

    def cpu(self) -> float:
        t = self.ps.cpu_times()
        return float(t.user + t.system)

    def rss(self) -> int:
        return int(self.ps.memory_info().rss)

    def peak_reset(self) -> None:
        """Reset the peak RSS (VmHWM) where the kernel allows it."""
        try:
            with open(f"/proc/{self.proc.pid}/clear_refs", "w") as f:
                f.write("5")
        except OSError:
            pass

    def peak(self) -> int:
        """Peak RSS (bytes) since :meth:`peak_reset`."""
        with open(f"/proc/{self.proc.pid}/status") as f:
            for line in f:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1]) * 1024
        return 0

    def close(self) -> None:
        self.proc.terminate()
        self.proc.wait(30)


class Sim(Measured):
    """A `wsg sim` subprocess on fixed ports (TCP, UDP; a pty with ``serial``)."""

    def __init__(self, count: int = 1, reply_port: int | None = None, serial: bool = False) -> None:
        self.base = free_base(2 * count + 1)
        self.tcp = self.base
        self.udp = self.base + count
        args = ["--tcp-port", str(self.tcp), "--udp-port", str(self.udp), "--udp-reply-port",
                str(reply_port if reply_port is not None else 0), "--serial", "pty" if serial else "off",
                "--web-port", "0", "--count", str(count), "--no-uvloop"]
        self.proc = subprocess.Popen([*SIM, *args], stdout=subprocess.PIPE, stderr=subprocess.DEVNULL,
                                     text=True, env=sim_env())
        assert self.proc.stdout is not None
        self.serial = ""  # the pty's path (serial=True)
        for _ in range(2 * count + serial):
            line = self.proc.stdout.readline()
            if not line:
                raise RuntimeError("wsg sim did not start")
            if "serial://" in line:
                self.serial = line.split("serial://", 1)[1].split("?")[0]
        self._watch()


def _nofile(n: int) -> None:
    """In the sim's process before exec: ``ulimit -n n`` (the common default of 1024)."""
    resource.setrlimit(resource.RLIMIT_NOFILE, (n, n))


class WebSim(Measured):
    """``wsg sim --host 0.0.0.0`` with TCP, Modbus/TCP and web, under ``ulimit -n 1024``; the web
    password is read from its stderr."""

    def __init__(self) -> None:
        import re

        self.base = free_base(3)
        self.tcp, self.modbus, self.web = self.base, self.base + 1, self.base + 2
        self.proc = subprocess.Popen(
            [*SIM, "--host", "0.0.0.0", "--tcp-port", str(self.tcp), "--udp-port", "0", "--serial", "off",
             "--modbus-port", str(self.modbus), "--web-port", str(self.web), "--no-uvloop"],
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=sim_env(),
            preexec_fn=lambda: _nofile(1024))
        assert self.proc.stdout is not None and self.proc.stderr is not None
        for _ in range(10):  # one line per interface; the web interface's comes last
            line = self.proc.stdout.readline()
            if not line:
                raise RuntimeError("wsg sim did not start")
            if str(self.web) in line:
                break
        line = self.proc.stderr.readline()  # "wsg web interface on HOST:PORT: password XYZ"
        m = re.search(r"password (\S+)", line)
        self.password = m.group(1) if m else ""
        threading.Thread(target=self.proc.stderr.read, daemon=True).start()  # keep draining it
        self._watch()


class ProxyRun(Measured):
    """``wsg proxy --to`` a sim's TCP port, printing text lines to a file, writing --jsonl (and --pcap)."""

    def __init__(self, sim: Sim, tmp: str, pcap: bool) -> None:
        self.port = free_base(1)
        self.text = os.path.join(tmp, "proxy.txt")
        self.jsonl = os.path.join(tmp, "proxy.jsonl")
        self.out = open(self.text, "w")  # noqa: SIM115 - closed in close()
        self.proc = subprocess.Popen([*SIM[:-1], "proxy", "--listen", str(self.port), "--to",
                                      f"tcp://127.0.0.1:{sim.tcp}", "--jsonl", self.jsonl,
                                      *(["--pcap", os.path.join(tmp, "proxy.pcapng")] if pcap else [])],
                                     stdout=self.out, stderr=subprocess.PIPE, text=True, env=sim_env())
        assert self.proc.stderr is not None
        if not self.proc.stderr.readline().startswith("proxy "):
            raise RuntimeError("wsg proxy did not start")
        self._watch()

    def log_bytes(self) -> int:
        return os.path.getsize(self.text) + os.path.getsize(self.jsonl)

    def close(self) -> None:
        super().close()
        self.out.close()


P = TypeVar("P", bound=Measured)


@contextmanager
def fresh(make: Callable[[], P], settle: float = 0.2) -> Iterator[P]:
    """A new process for one measurement, given ``settle`` s to start its loops; closed after."""
    p = make()
    try:
        time.sleep(settle)
        yield p
    finally:
        p.close()


# ---------------------------------------------------------------- the other client
def summary(waits: Sequence[float], empty: float = float("nan")) -> tuple[float, float, float]:
    """(p50, p99, max) of ``waits`` in s (``empty`` when there are none)."""
    w = sorted(waits) or [empty]
    return w[len(w) // 2], w[min(len(w) - 1, int(len(w) * 0.99))], w[-1]


class Waiter(threading.Thread):
    """The other client: Loop requests back to back over UDP (``port``) or, with ``tcp``, over one
    TCP connection; records each wait (s)."""

    def __init__(self, port: int, tcp: bool = False) -> None:
        super().__init__(daemon=True)
        if tcp:
            self.sock = socket.create_connection(("127.0.0.1", port))
            self.sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        else:
            self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            self.sock.bind(("127.0.0.1", 0))
        self.sock.settimeout(10)
        self.port = port
        self.tcp = tcp
        self.waits: list[float] = []
        self.lost = 0
        self.stop = threading.Event()

    def _ask(self, req: bytes, parser: FrameParser) -> None:
        if self.tcp:
            self.sock.sendall(req)
            while not any(isinstance(e, Frame) for e in parser.feed(self.sock.recv(4096))):
                pass
        else:
            self.sock.sendto(req, ("127.0.0.1", self.port))
            self.sock.recvfrom(2048)

    def run(self) -> None:
        n = 0
        parser = FrameParser()
        while not self.stop.is_set():
            n += 1
            req = Frame(0x06, n.to_bytes(4, "little")).encode()
            t0 = time.perf_counter()
            try:
                self._ask(req, parser)
            except TimeoutError:
                self.lost += 1
                continue
            self.waits.append(time.perf_counter() - t0)
            time.sleep(0.0005)

    def finish(self) -> tuple[float, float, float]:
        """Stop; (p50, p99, max) wait in s."""
        self.stop.set()
        self.join(15)
        self.sock.close()
        return summary(self.waits)


@contextmanager
def waiting(port: int, tcp: bool = False, settle: float = 0.2) -> Iterator[Waiter]:
    """The other client runs for the block (given ``settle`` s first); ``.finish()`` for its waits."""
    w = Waiter(port, tcp)
    w.start()
    time.sleep(settle)
    try:
        yield w
    finally:
        if not w.stop.is_set():
            w.finish()


def waits_text(waits: tuple[float, float, float]) -> str:
    p50, p99, worst = waits
    return f"other client p50/p99/max {p50 * 1e3:.0f}/{p99 * 1e3:.0f}/{worst * 1e3:.0f} ms"


# ---------------------------------------------------------------- cases
T = TypeVar("T")


@dataclass
class Case(Generic[T]):
    """One row: ``name``, the bytes it sends (0: not a per-MiB figure), ``attack`` on the process the
    table makes, and anything else the table's runner needs in ``extra``."""

    name: str
    attack: Callable[[T], Any]
    sent: int = 0
    extra: Any = None


def picked(name: str, only: Sequence[str]) -> bool:
    """``--only``: run a case whose name holds one of the substrings (all when none given)."""
    return not only or any(o in name for o in only)


def run_table(cases: Sequence[Case[T]], only: Sequence[str], row: Callable[[Case[T]], str],
              header: str = "") -> None:
    """Print ``header`` and ``row(case)`` for each case ``--only`` picks."""
    if header:
        print(header, flush=True)
    for case in (c for c in cases if picked(c.name, only)):
        print(f"{case.name:44s} {row(case)}", flush=True)
