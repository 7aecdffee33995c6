"""Free ports for servers a test starts in another process (which must be told a number).

Picked at random below the kernel's ephemeral range (``ip_local_port_range``, 32768-60999 by
default): the ports the kernel hands out meanwhile - every connection's local port, every server
bound to port 0 in a parallel test - come from that range, so they can never take a port picked here
between the check and the server's bind. Two parallel tests picking the same port is the one race
left, at about one chance in 20,000 per pair. A server the test runs in-process binds port 0 instead.
"""

from __future__ import annotations

import random
import socket

_LOW, _HIGH = 10_000, 32_000


def _ephemeral_low() -> int:
    try:
        with open("/proc/sys/net/ipv4/ip_local_port_range") as f:
            return int(f.read().split()[0])
    except (OSError, ValueError, IndexError):
        return 32_768


def free_base(n: int = 1) -> int:
    """A port p such that p..p+n-1 are free for TCP and UDP on 127.0.0.1, below the ephemeral range."""
    high = min(_HIGH, _ephemeral_low() - n)
    for _ in range(500):
        base = random.randint(_LOW, high)
        socks: list[socket.socket] = []
        try:
            for i in range(n):
                for kind in (socket.SOCK_STREAM, socket.SOCK_DGRAM):
                    s = socket.socket(socket.AF_INET, kind)
                    socks.append(s)
                    s.bind(("127.0.0.1", base + i))
            return base
        except OSError:
            continue
        finally:
            for s in socks:
                s.close()
    raise RuntimeError("no free port range below the ephemeral ports")


def free_port(kind: int = socket.SOCK_STREAM) -> int:
    """One free port (for TCP and UDP alike, whatever ``kind``), below the ephemeral range."""
    del kind  # free_base checks both
    return free_base(1)
