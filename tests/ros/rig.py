"""The ROS test rig: a virtual WSG (``wsg sim``'s server, in this process, with its world API), the
node as ``wsg ros`` in a process of the ROS venv, and a second rclpy process as the client
(tests/ros/rosclient.py), all on loopback in a ROS domain of their own.

The ROS venv is the one scripts/ros-env.sh builds (.venv-ros; ``PYWSG_ROS_VENV`` overrides); without it
the tests skip, saying so."""

from __future__ import annotations

import fcntl
import json
import os
import queue
import signal
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

import pytest

from pywsg.testing import SimThread

ROOT = Path(__file__).resolve().parents[2]
VENV = Path(os.environ.get("PYWSG_ROS_VENV", ROOT / ".venv-ros"))
READY = VENV / "pywsg-ros-ready"
CLIENT = Path(__file__).with_name("rosclient.py")



def venv_python() -> str:
    """X.Y of the ROS venv's Python ("" when there is none)."""
    try:
        cfg = (VENV / "pyvenv.cfg").read_text()
    except OSError:
        return ""
    for line in cfg.splitlines():
        key, _, value = line.partition("=")
        if key.strip() in ("version", "version_info"):
            return ".".join(value.strip().split(".")[:2])
    return ""


def skip_reason() -> str | None:
    """Why the ROS tests cannot run here, or None. They run once per suite: on the interpreter of the ROS
    venv (scripts/test.sh's main run); the runs on other Pythons (scripts/other-python.sh) would start the
    same ROS processes of .venv-ros again."""
    if not READY.exists():
        return f"the ROS 2 test environment is not built: run scripts/ros-env.sh (looked for {READY})"
    here = f"{sys.version_info[0]}.{sys.version_info[1]}"
    if venv_python() and venv_python() != here:
        return f"the ROS tests run on the ROS venv's Python {venv_python()} (this is {here}): once per suite"
    return None


needs_ros = pytest.mark.skipif(skip_reason() is not None, reason=skip_reason() or "")

NODE = "wsg_gripper"
LEGACY = "wsg_50_driver"
#: s to wait for the first answer of a new process (discovery, the first service call: ~3 s on a loaded machine)
FIRST = 60.0


def shm_entries() -> set[str]:
    """Fast DDS's shared-memory files in /dev/shm (segments, port locks, semaphores)."""
    try:
        return {n for n in os.listdir("/dev/shm") if "fastrtps" in n or "fastdds" in n or "fast_datasharing" in n}
    except FileNotFoundError:
        return set()


def shm_in_use() -> set[str]:
    """The /dev/shm files some live process has open or mapped (a ROS process of another test, say)."""
    used: set[str] = set()
    for pid in filter(str.isdigit, os.listdir("/proc")):
        try:
            with open(f"/proc/{pid}/maps") as f:
                used.update(line.rsplit("/dev/shm/", 1)[1].split()[0] for line in f if "/dev/shm/" in line)
            for fd in os.listdir(f"/proc/{pid}/fd"):
                target = os.readlink(f"/proc/{pid}/fd/{fd}")
                if target.startswith("/dev/shm/"):
                    used.add(target[len("/dev/shm/"):])
        except OSError:  # the process ended meanwhile, or is not ours to read
            continue
    return used


def shm_left_behind(before: set[str]) -> set[str]:
    """Fast DDS files that appeared since ``before`` and that no live process uses: left behind. (Its
    shared-memory transport stays on: with ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST the RMW picks the
    transports itself, whatever a profile says; a clean exit removes the files.)"""
    new = shm_entries() - before
    if not new:
        return set()
    left = new - shm_in_use()
    # a port's semaphore (sem.fastdds_portN_mutex) is not held open between uses: it belongs to its port's
    # segment, and is left behind only when that segment is gone or unused too
    return {n for n in left if not (n.startswith("sem.") and n[4:].removesuffix("_mutex") in shm_entries() - left)}


def ros_env(log_dir: Path, domain: int) -> dict[str, str]:
    """The environment of the ROS processes: their own domain, discovery confined to this host."""
    env = {k: v for k, v in os.environ.items() if not k.startswith(("PYTEST", "COV_", "VIRTUAL_ENV"))}
    env.pop("PYTHONPATH", None)
    env.update(ROS_DOMAIN_ID=str(domain), ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST",
               RMW_IMPLEMENTATION="rmw_fastrtps_cpp", ROS_LOG_DIR=str(log_dir), PYTHONUNBUFFERED="1",
               RCUTILS_COLORIZED_OUTPUT="0")
    return env


class Domain:
    """A ROS domain (1..100, inside Fast DDS's port range) that no other rig on this machine uses while this
    one lives: each rig holds an exclusive lock on a file named by its domain (any process, any worker)."""

    def __init__(self) -> None:
        start = os.getpid() % 100
        for i in range(100):
            number = 1 + (start + i) % 100
            f = open(Path(tempfile.gettempdir()) / f"pywsg-ros-domain-{number}.lock", "w")  # noqa: SIM115
            try:
                fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError:
                f.close()
                continue
            self.number, self._file = number, f
            return
        raise RuntimeError("no free ROS domain: 100 rigs running?")

    def release(self) -> None:
        self._file.close()  # closing drops the lock


class Lines:
    """A process's stdout, line by line, read on a thread (so a wait can time out)."""

    def __init__(self, proc: subprocess.Popen[str]) -> None:
        self.q: queue.Queue[str | None] = queue.Queue()
        self.seen: list[str] = []
        assert proc.stdout is not None
        out = proc.stdout

        def pump() -> None:
            for line in out:
                self.q.put(line)
            self.q.put(None)
        threading.Thread(target=pump, daemon=True).start()

    def get(self, timeout: float) -> str:
        try:
            line = self.q.get(timeout=timeout)
        except queue.Empty:
            raise TimeoutError(f"no line within {timeout} s; seen: {self.seen[-5:]}") from None
        if line is None:
            raise EOFError(f"the process ended; its last lines: {self.seen[-20:]}")
        self.seen.append(line)
        return line


class Rig:
    """Sim + node process + client process; ``rig.call(op, **kw)`` asks the client (see rosclient.py)."""

    def __init__(self, tmp: Path, *, params: dict[str, Any] | None = None, autostart: bool = True,
                 params_file: Path | None = None) -> None:
        self.tmp = tmp
        self.shm_before = shm_entries()
        self.sim = SimThread(udp_port=None).start()
        self.world = self.sim.world
        self.domain = Domain()
        self.env = ros_env(tmp, self.domain.number)
        self.node: subprocess.Popen[str] | None = None
        self.client: subprocess.Popen[str] | None = None
        self.node_log = tmp / "node.log"
        self.params = {"speed": 400.0, "joint_state_rate": 50.0, "diagnostics_rate": 5.0, **(params or {})}
        self.autostart = autostart
        self.params_file = params_file
        self._out: Lines | None = None
        self.world_after: dict[str, Any] = {}

    def start(self) -> Rig:
        try:
            self.start_node()
            self.client = subprocess.Popen(
                [str(VENV / "bin" / "python"), str(CLIENT), f"/{NODE}", LEGACY], env=self.env, cwd=self.tmp,
                stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=(self.tmp / "client.log").open("w"), text=True)
            self._out = Lines(self.client)
            assert json.loads(self._out.get(FIRST))["ready"]
            if self.autostart:
                self.call("wait", active=True)
        except BaseException:
            self.close()
            raise
        return self

    def start_node(self, **params: Any) -> None:
        ros_args = ["--ros-args", "--log-level", "info"]
        if self.params_file is not None:
            ros_args += ["--params-file", str(self.params_file)]
        for k, v in {**self.params, "autostart": self.autostart, **params}.items():
            ros_args += ["-p", f"{k}:={json.dumps(v) if not isinstance(v, str) else v}"]
        self.node = subprocess.Popen(
            [str(VENV / "bin" / "wsg"), "ros", "--url", self.sim.url, "--name", NODE, *ros_args], env=self.env,
            cwd=self.tmp, stdin=subprocess.DEVNULL, stdout=self.node_log.open("a"), stderr=subprocess.STDOUT,
            text=True)

    def call(self, op: str, timeout: float = FIRST, **kw: Any) -> dict[str, Any]:
        assert self.client is not None and self.client.stdin is not None and self._out is not None
        self.client.stdin.write(json.dumps({"op": op, **kw}) + "\n")
        self.client.stdin.flush()
        out: dict[str, Any] = json.loads(self._out.get(timeout))
        if not out.pop("ok"):
            raise AssertionError(f"{op}: {out['error']}\n{out.get('trace', '')}\nnode log:\n{self.log_tail()}")
        return out

    def log_tail(self, n: int = 30) -> str:
        try:
            return "\n".join(self.node_log.read_text().splitlines()[-n:])
        except OSError:
            return ""

    def stop_node(self, timeout: float = 20.0) -> int:
        """SIGTERM the node (as a launch system does) and wait: its exit status."""
        node, self.node = self.node, None
        if node is None:
            return 0
        if node.poll() is None:
            node.send_signal(signal.SIGTERM)
        try:
            return node.wait(timeout)
        except subprocess.TimeoutExpired:
            node.kill()
            node.wait(5)
            return -9

    def close(self) -> int:
        """Stop both processes and the sim; the node's exit status."""
        if self.client is not None:
            client, self.client = self.client, None
            try:
                assert client.stdin is not None
                client.stdin.write(json.dumps({"op": "quit"}) + "\n")
                client.stdin.close()
                client.wait(15)
            except (OSError, subprocess.TimeoutExpired):
                client.kill()
                client.wait(5)
        status = self.stop_node()
        self.world_after = self.world.state()
        self.sim.stop()
        self.domain.release()
        return status

    def sessions(self) -> int:
        """TCP connections the sim serves now."""
        tcp = self.sim.g.tcp
        assert tcp is not None
        return self.sim.call(lambda: len(tcp.connections))


def wait_until(predicate: Any, timeout: float = 15.0, step: float = 0.02) -> bool:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if predicate():
            return True
        time.sleep(step)
    return bool(predicate())
