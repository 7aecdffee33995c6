"""The per-client token buckets of the web interface's request rate limit (``server/ratelimit.py``).

The clock is a plain function the test advances, so refill and eviction are exact; the limit in
the running web interface is tested over real sockets in tests/web/test_request_rate.py.
"""

from __future__ import annotations

import pytest

from pywsg.server.ratelimit import OVERFLOW, RequestRate, client_key, retry_after


class Clock:
    def __init__(self) -> None:
        self.now = 1000.0

    def __call__(self) -> float:
        return self.now


def test_a_burst_then_the_rate() -> None:
    clock = Clock()
    r = RequestRate(rate=2.0, burst=3, clock=clock)
    assert [r.take("a") for _ in range(3)] == [0.0, 0.0, 0.0]
    assert r.take("a") == pytest.approx(0.5)  # one token refills in 1/rate s
    assert r.refused == 1
    clock.now += 0.5
    assert r.take("a") == 0.0
    assert r.take("a") > 0
    clock.now += 100  # refills to the burst, not beyond
    assert [r.take("a") for _ in range(4)].count(0.0) == 3


def test_clients_have_their_own_buckets() -> None:
    r = RequestRate(rate=1.0, burst=1, clock=Clock())
    assert r.take("a") == 0.0 and r.take("a") > 0
    assert r.take("b") == 0.0


def test_the_table_is_bounded_refilled_buckets_go_first_then_an_overflow_bucket() -> None:
    clock = Clock()
    r = RequestRate(rate=1.0, burst=2, max_clients=3, clock=clock)
    for key in "abc":
        r.take(key)
    assert len(r) == 3
    # every bucket still in use: a fourth address shares the overflow bucket (burst 2)
    assert [r.take("d"), r.take("e"), r.take("f")][:2] == [0.0, 0.0]
    assert r.take("g") > 0 and len(r) == 3
    # once the least recently used bucket has refilled, it makes room for a new address
    clock.now += 1.0
    assert r.take("h") == 0.0 and len(r) == 3
    assert "h" in r._buckets and "a" not in r._buckets
    assert OVERFLOW not in r._buckets


def test_many_addresses_cost_a_bounded_table() -> None:
    clock = Clock()
    r = RequestRate(rate=10.0, burst=5, max_clients=100, clock=clock)
    for i in range(100_000):
        clock.now += 0.0001
        r.take(f"10.{i >> 16 & 255}.{i >> 8 & 255}.{i & 255}")
    assert len(r) == 100


def test_keys() -> None:
    assert client_key("192.0.2.7") == "192.0.2.7"
    assert client_key("::ffff:192.0.2.7") == "192.0.2.7"  # IPv4-mapped: the IPv4 client
    # a host holds a whole /64: its addresses share one bucket
    assert client_key("2001:db8:1:2::1") == client_key("2001:db8:1:2:ffff::9") == "2001:db8:1:2::/64"
    assert client_key("2001:db8:1:3::1") != client_key("2001:db8:1:2::1")
    assert client_key("fe80::1%eth0") == "fe80::/64"


def test_retry_after_is_whole_seconds_at_least_one() -> None:
    assert retry_after(0.05) == 1 and retry_after(1.0) == 1 and retry_after(1.2) == 2


def test_bad_parameters() -> None:
    for kwargs in ({"rate": 0, "burst": 1}, {"rate": 1, "burst": 0}, {"rate": 1, "burst": 1, "max_clients": 0}):
        with pytest.raises(ValueError):
            RequestRate(**kwargs)


def test_many_addresses_together_are_bounded_by_the_total() -> None:
    """Issue 33 item 11: 64 loopback addresses each got their own burst (20,889 answers for 1 MiB,
    50 times one address's CPU). The total bucket holds TOTAL_FACTOR bursts and refills at that rate."""
    from pywsg.server.ratelimit import TOTAL_FACTOR

    clock = Clock()
    r = RequestRate(rate=20.0, burst=200, clock=clock)
    served = sum(r.take(f"127.0.0.{1 + i % 64}") == 0.0 for i in range(64 * 200))
    assert served == 200 * TOTAL_FACTOR  # not 64 bursts
    clock.now += 1.0  # one second refills the total at TOTAL_FACTOR x the rate
    served = sum(r.take(f"127.0.0.{1 + i % 64}") == 0.0 for i in range(64 * 200))
    assert served == 20 * TOTAL_FACTOR
    # one client alone is still limited by its own bucket first
    clock.now += 100.0
    assert [r.take("192.0.2.1") for _ in range(201)].count(0.0) == 200
