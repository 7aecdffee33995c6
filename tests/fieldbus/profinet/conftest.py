"""PROFINET tests on a real wire: each test gets two network namespaces of its own joined by a veth pair.

The device (``wsg sim --profinet eth0``) runs in the "device" namespace, the controller (profinet-py, a
raw-socket client, tshark) in the "controller" namespace, so nothing touches the host's interfaces and
the controller can bind UDP 34964 without meeting another test. Both namespaces are deleted at teardown,
also on failure, after every process started in them is killed. Without CAP_NET_ADMIN (not root) the
tests skip, saying so; CI runs as root.
"""

from __future__ import annotations

import ctypes
import itertools
import json
import os
import queue
import shutil
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import pytest

HERE = Path(__file__).resolve().parent
CONTROLLER = HERE / "pn_controller.py"
DEVICE_IP, CONTROLLER_IP = "192.168.77.2", "192.168.77.1"
STATION = "wsg-test"
WSG = [sys.executable, "-c", "from pywsg.cli.main import main; main()"]
_counter = itertools.count()


def _cap_net_admin() -> str | None:
    """None when namespaces can be made here, else why not."""
    if shutil.which("ip") is None:
        return "iproute2's `ip` is not installed"
    try:
        status = Path("/proc/self/status").read_text()
    except OSError:
        return "no /proc/self/status (not Linux)"
    cap = next((int(line.split()[1], 16) for line in status.splitlines() if line.startswith("CapEff:")), 0)
    if not cap >> 12 & 1:
        return "needs CAP_NET_ADMIN (run as root) to make a network namespace with a veth pair"
    return None


def _ip(*args: str) -> None:
    subprocess.run(["ip", *args], check=True, capture_output=True, timeout=20)


@dataclass
class Wire:
    """Two namespaces and the processes started in them (killed at teardown)."""

    device_ns: str
    controller_ns: str
    iface: str = "eth0"
    procs: list[subprocess.Popen[str]] = field(default_factory=list)
    sockets: list[socket.socket] = field(default_factory=list)

    def popen(self, ns: str, argv: list[str], **kw: object) -> subprocess.Popen[str]:
        p = subprocess.Popen(["ip", "netns", "exec", ns, *argv], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                             text=True, **kw)  # type: ignore[call-overload]
        self.procs.append(p)
        return p

    def sim(self, *extra: str, name: str | None = STATION, ip: str | None = f"{DEVICE_IP}/24",
            web: bool = False) -> Sim:
        argv = [*WSG, "sim", "--json", "--no-uvloop",
                "--tcp-port", "0", "--udp-port", "0", "--serial", "off", "--web-port", "off",
                "--profinet", self.iface]
        if name is not None:
            argv += ["--profinet-name", name]
        if ip is not None:
            argv += ["--profinet-ip", ip]
        if web:
            argv += ["--web-port", "0"]
        p = self.popen(self.device_ns, [*argv, *extra])
        lines = _read_lines(p, 20.0, ['"profinet"', *(['"web"'] if web else [])])
        sim = Sim(p, json.loads(lines[0]))
        if web:
            sim.web_url = str(json.loads(lines[1])["url"]).rstrip("/")
        return sim

    def http(self, method: str, url: str, body: object = None) -> object:
        """An HTTP request from inside the device namespace (where the sim's web interface listens)."""
        code = ("import httpx, json, sys; from urllib.parse import urlsplit\n"
                "u = urlsplit(sys.argv[2]); c = httpx.Client(base_url=f'{u.scheme}://{u.netloc}', timeout=20)\n"
                "t = c.get('/api/csrf').json()['token']\n"   # a loopback session still sends the CSRF token
                "r = c.request(sys.argv[1], u.path, json=json.loads(sys.argv[3]), headers={'x-csrf-token': t})\n"
                "print(json.dumps({'status': r.status_code, 'body': r.json()}))")
        r = subprocess.run(["ip", "netns", "exec", self.device_ns, sys.executable, "-c", code, method, url,
                            json.dumps(body)], capture_output=True, text=True, timeout=60)
        assert r.returncode == 0, r.stderr
        return json.loads(r.stdout)

    def controller(self, *args: str, timeout: float = 60.0, argv: list[str] | None = None) -> dict[str, object]:
        """Run one scenario of pn_controller.py (or ``argv``) in the controller namespace; its last stdout
        line (JSON), with the JSON lines before it as ``stdout`` and the end of its stderr as ``stderr``."""
        p = self.popen(self.controller_ns, argv or [sys.executable, str(CONTROLLER), self.iface, *args])
        try:
            out, err = p.communicate(timeout=timeout)
        except subprocess.TimeoutExpired:
            p.kill()
            out, err = p.communicate()
            raise AssertionError(f"controller {args} still running after {timeout} s; stderr:\n{err[-3000:]}") from None
        lines = [ln for ln in out.splitlines() if ln.startswith("{")]
        why = f"controller {args or argv} exited {p.returncode}:\n{out[-2000:]}\n{err[-3000:]}"
        assert (p.returncode == 0 or argv) and lines, why
        result: dict[str, object] = json.loads(lines[-1])
        # what the controller printed and logged before: for an assertion's message when one fails
        result["stdout"], result["stderr"] = "\n".join(lines[-40:-1]), err[-3000:]
        return result

    def socket_in(self, ns: str, family: int, kind: int, proto: int = 0) -> socket.socket:
        """A socket made inside namespace ``ns`` (a socket keeps its namespace for life): a helper thread
        enters the namespace with setns(2), so this process stays where it is."""
        made: list[socket.socket | BaseException] = []

        def enter() -> None:
            try:
                libc = ctypes.CDLL(None, use_errno=True)
                fd = os.open(f"/run/netns/{ns}", os.O_RDONLY)
                try:
                    if libc.setns(fd, 0x40000000) != 0:   # CLONE_NEWNET
                        raise OSError(ctypes.get_errno(), "setns")
                finally:
                    os.close(fd)
                made.append(socket.socket(family, kind, proto))
            except BaseException as exc:
                made.append(exc)

        t = threading.Thread(target=enter)
        t.start()
        t.join(10)
        result = made[0]
        if isinstance(result, BaseException):
            raise result
        self.sockets.append(result)
        return result

    def close(self) -> None:
        for sock in self.sockets:
            sock.close()
        for p in self.procs:
            if p.poll() is None:
                p.kill()
            try:
                p.communicate(timeout=10)
            except (subprocess.TimeoutExpired, ValueError):
                pass


@dataclass
class Sim:
    proc: subprocess.Popen[str]
    banner: dict[str, object]
    web_url: str = ""

    def stop(self) -> str:
        """SIGTERM, wait; its stderr."""
        self.proc.terminate()
        self.proc.wait(timeout=15)
        assert self.proc.stderr is not None
        return self.proc.stderr.read()


def _read_lines(p: subprocess.Popen[str], timeout: float, wanted: list[str]) -> list[str]:
    """For each text in ``wanted`` the first stdout line holding it (a reader thread: select() cannot see
    text-buffered lines)."""
    assert p.stdout is not None
    lines: queue.Queue[str] = queue.Queue()
    stdout = p.stdout

    def pump() -> None:
        for line in stdout:
            lines.put(line)
        lines.put("")

    threading.Thread(target=pump, daemon=True).start()
    deadline = time.monotonic() + timeout
    seen: list[str] = []
    found: dict[str, str] = {}
    while time.monotonic() < deadline and len(found) < len(wanted):
        try:
            line = lines.get(timeout=0.2)
        except queue.Empty:
            continue
        if not line:
            break
        seen.append(line)
        for w in wanted:
            if w in line and w not in found:
                found[w] = line
    if len(found) == len(wanted):
        return [found[w] for w in wanted]
    err = p.stderr.read() if p.stderr and p.poll() is not None else ""
    raise AssertionError(f"wsg sim printed no {wanted} lines within {timeout} s: {seen} {err}")


@pytest.fixture
def wire() -> Iterator[Wire]:
    why = _cap_net_admin()
    if why:
        pytest.skip(f"PROFINET wire tests: {why}")
    tag = f"pnt{os.getpid()}-{next(_counter)}"
    dev, ctl = f"{tag}-dev", f"{tag}-ctl"
    w = Wire(dev, ctl)
    try:
        _ip("netns", "add", dev)
        _ip("netns", "add", ctl)
        _ip("-n", dev, "link", "add", "eth0", "type", "veth", "peer", "name", "eth0", "netns", ctl)
        for ns in (dev, ctl):
            # no IPv6 router solicitations or MLD reports on the wire: the capture holds the session only
            subprocess.run(["ip", "netns", "exec", ns, "sysctl", "-q", "-w", "net.ipv6.conf.all.disable_ipv6=1",
                            "net.ipv6.conf.default.disable_ipv6=1"], capture_output=True, timeout=20)
            _ip("-n", ns, "link", "set", "lo", "up")
        _ip("-n", ctl, "addr", "add", f"{CONTROLLER_IP}/24", "dev", "eth0")
        for ns in (dev, ctl):
            _ip("-n", ns, "link", "set", "eth0", "up")
        yield w
    finally:
        w.close()
        for ns in (dev, ctl):
            subprocess.run(["ip", "netns", "del", ns], capture_output=True, timeout=20)
