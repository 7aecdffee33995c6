"""Per-client request rate limit: one token bucket per client address (like nginx ``limit_req``).

Each client address has a bucket of ``burst`` tokens that refills at ``rate`` tokens per second;
every request takes one token, and a request finding the bucket empty is refused (the web interface
answers it with ``429 Too Many Requests`` and ``Retry-After``). A client that stays under ``rate``
on average never notices; a client sending as fast as it can gets ``burst`` requests and then
``rate`` per second, whatever number of connections it spreads them over.

The table is bounded: at most ``max_clients`` addresses have a bucket of their own. A bucket that
has refilled carries no information (a new one is the same), so it is dropped to make room; when
every bucket in the table is still in use, further addresses share one overflow bucket, so a flood
from many addresses costs at most ``max_clients`` buckets of memory and one more burst.

Many addresses together are bounded too: one more bucket, shared by every request, holds
``TOTAL_FACTOR`` times the burst and refills at ``TOTAL_FACTOR`` times the rate. Without it 64
loopback addresses got 20,889 answers for 1 MiB of pipelined requests (14.6 s of CPU, 50 times one
address's cost); a request is served only when its own bucket and the total both hold a token.

IPv6 clients are keyed by their /64 prefix (one host usually holds a whole /64, so per-address
buckets would give it 2^64 bursts); IPv4-mapped IPv6 addresses count as the IPv4 address.
"""

from __future__ import annotations

import ipaddress
import math
import time
from collections import OrderedDict
from collections.abc import Callable

OVERFLOW = "*"
"""The key of the bucket shared by addresses that find the table full."""

TOTAL_FACTOR = 5
"""The bucket shared by all clients: this many times one client's burst and rate (a handful of browsers
and scripts at their limit at once)."""


def client_key(host: str) -> str:
    """The bucket key for a peer address: the IPv4 address, or the /64 of an IPv6 address."""
    if ":" not in host:
        return host
    try:
        addr = ipaddress.IPv6Address(host.split("%", 1)[0])
    except ValueError:
        return host
    if addr.ipv4_mapped is not None:
        return str(addr.ipv4_mapped)
    return str(ipaddress.IPv6Network((int(addr) >> 64 << 64, 64)))


class RequestRate:
    """Token buckets per client key: ``rate`` requests per second on average, bursts of ``burst``.

    ``max_clients``: buckets kept (about 260 bytes each); ``clock``: seconds, monotonic.
    """

    def __init__(self, rate: float, burst: int, max_clients: int = 4096,
                 clock: Callable[[], float] = time.monotonic, total_factor: float = TOTAL_FACTOR) -> None:
        if not rate > 0 or burst < 1 or max_clients < 1 or not total_factor >= 1:
            raise ValueError("rate must be > 0 requests/s, burst and max_clients at least 1, total_factor >= 1")
        self.rate = float(rate)
        self.burst = int(burst)
        self.total_rate = self.rate * total_factor
        self.total_burst = float(self.burst * total_factor)
        self._total = [self.total_burst, clock()]
        self.max_clients = max_clients
        self.clock = clock
        # key -> [tokens, time of that count]; least recently used first
        self._buckets: OrderedDict[str, list[float]] = OrderedDict()
        self._overflow = [float(burst), clock()]
        self.refused = 0
        """Requests refused so far (all clients)."""

    def __len__(self) -> int:
        return len(self._buckets)

    def _bucket(self, key: str, now: float) -> list[float]:
        b = self._buckets.get(key)
        if b is not None:
            self._buckets.move_to_end(key)
            return b
        if len(self._buckets) >= self.max_clients:
            # the least recently used bucket, if it has refilled, is as good as none
            old_key, old = next(iter(self._buckets.items()))
            if old[0] + (now - old[1]) * self.rate < self.burst:
                return self._overflow
            del self._buckets[old_key]
        b = self._buckets[key] = [float(self.burst), now]
        return b

    def take(self, key: str) -> float:
        """Spend one token of ``key``'s bucket: 0.0 if the request may go ahead, else the seconds
        until the bucket holds a token again (the request is refused and spends nothing)."""
        now = self.clock()
        b = self._bucket(key, now)
        tokens = min(float(self.burst), b[0] + (now - b[1]) * self.rate)
        b[1] = now
        t = self._total
        total = min(self.total_burst, t[0] + (now - t[1]) * self.total_rate)
        t[1] = now
        if tokens >= 1.0 and total >= 1.0:
            b[0] = tokens - 1.0
            t[0] = total - 1.0
            return 0.0
        b[0], t[0] = tokens, total
        self.refused += 1
        return max((1.0 - tokens) / self.rate, (1.0 - total) / self.total_rate)


def retry_after(wait: float) -> int:
    """``wait`` (s, from :meth:`RequestRate.take`) as a ``Retry-After`` value: whole seconds, at least 1."""
    return max(1, math.ceil(wait))

