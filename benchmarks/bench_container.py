"""The container image (docs/container.md): size, start-up, memory per gripper with --count and per pod.

Needs podman and the image (``scripts/container-env.sh image`` builds ``localhost/pywsg-sim:test``;
``--image NAME`` for another). Printed:

- the image's and its base's size (MB, as ``podman image inspect`` counts them);
- start-up: seconds from ``podman run -d`` to the first 200 from ``/healthz`` (median of ``--runs``),
  beside the bare baseline from the same run: ``wsg sim`` started on the host the same way (a new Python
  process, the same interfaces), and ``podman run`` of ``true`` in the same image (the container's own cost);
- memory: the RSS of ``wsg sim`` (PID 1 in the container) with ``WSG_SIM_COUNT`` = 1, 10, 100 (each gripper
  with its TCP, UDP and web servers), i.e. what each further gripper in one container costs, against one
  gripper per container (a pod of its own).

    .venv/bin/python benchmarks/bench_container.py [--runs 5] [--image localhost/pywsg-sim:test]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CONF = ROOT / ".venv" / "container" / "containers.conf"
sys.path.insert(0, str(ROOT))
from tests.ports import free_base  # noqa: E402


def podman(*args: str, check: bool = True) -> str:
    r = subprocess.run(["podman", *args], env=dict(os.environ, CONTAINERS_CONF=str(CONF)), capture_output=True,
                       text=True, timeout=300)
    if check and r.returncode:
        raise RuntimeError(f"podman {args}: {r.stderr}")
    return r.stdout


def until_healthy(url: str, t0: float, timeout: float = 60) -> float:
    while time.monotonic() - t0 < timeout:
        try:
            with urllib.request.urlopen(url + "/healthz", timeout=2) as reply:
                if reply.status == 200:
                    return time.monotonic() - t0
        except OSError:
            pass
        time.sleep(0.01)
    raise TimeoutError(url)


def container_start(image: str, count: int = 1) -> tuple[float, int]:
    """(seconds to /healthz, RSS of the sim in kB) for one container with ``count`` grippers."""
    base = free_base(2)
    name = f"pywsg-bench-{os.getpid()}-{base}"
    t0 = time.monotonic()
    podman("run", "-d", "--name", name, "-e", "WSG_WEB_PASSWORD=bench", "-e", f"WSG_SIM_COUNT={count}",
           "-p", f"127.0.0.1:{base}:8080", "-p", f"127.0.0.1:{base + 1}:{8080 + count - 1}", image)
    try:
        ready = until_healthy(f"http://127.0.0.1:{base}", t0)
        until_healthy(f"http://127.0.0.1:{base + 1}", t0, timeout=300)   # the last gripper is up too
        time.sleep(0.5)
        status = podman("exec", name, "cat", "/proc/1/status")
        rss = next(int(line.split()[1]) for line in status.splitlines() if line.startswith("VmRSS:"))
        return ready, rss
    finally:
        podman("rm", "-f", "-v", name, check=False)


def host_start() -> float:
    """Seconds from spawning ``wsg sim`` on the host to /healthz (the baseline)."""
    base = free_base(3)
    argv = [sys.executable, "-c", "from pywsg.cli.main import main; main()", "sim", "--tcp-port", str(base),
            "--udp-port", str(base + 1), "--web-port", str(base + 2), "--serial", "off"]
    t0 = time.monotonic()
    p = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                         env=dict(os.environ, WSG_NO_ENV="1"))
    try:
        return until_healthy(f"http://127.0.0.1:{base + 2}", t0)
    finally:
        p.terminate()
        p.wait(timeout=20)


def bare_container(image: str) -> float:
    t0 = time.monotonic()
    podman("run", "--rm", "--entrypoint", "true", image)
    return time.monotonic() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--image", default="localhost/pywsg-sim:test")
    args = ap.parse_args()
    print(f"machine: {os.cpu_count()} cores, load average {os.getloadavg()[0]:.2f} at start")
    info = json.loads(podman("image", "inspect", args.image))[0]
    print(f"image {args.image}: {info['Size'] / 1e6:.0f} MB")
    for base in ("pywsg-base:bookworm",):
        out = podman("image", "inspect", base, check=False)
        if out:
            print(f"base  {base}: {json.loads(out)[0]['Size'] / 1e6:.0f} MB")
    host = [host_start() for _ in range(args.runs)]
    bare = [bare_container(args.image) for _ in range(args.runs)]
    runs = [container_start(args.image) for _ in range(args.runs)]
    print(f"start-up, median of {args.runs} (s):  container to /healthz {statistics.median(r[0] for r in runs):.2f}"
          f"   baseline: wsg sim on the host {statistics.median(host):.2f}, "
          f"podman run of `true` {statistics.median(bare):.2f}")
    one = statistics.median(r[1] for r in runs)
    print(f"memory: one gripper per container {one / 1024:.1f} MB (RSS of wsg sim)")
    for count in (10, 100):
        ready, rss = container_start(args.image, count)
        print(f"memory: --count {count:3d} in one container {rss / 1024:.1f} MB, "
              f"{(rss - one) / (count - 1) / 1024:.2f} MB per further gripper (ready in {ready:.2f} s)")
    print(f"load average {os.getloadavg()[0]:.2f} at the end")


if __name__ == "__main__":
    main()
