"""What ``/api/world/net`` and ``wsg proxy --control`` accept (issue 33 item 5): a 400-digit ``ms``, ``jitter``,
``p`` or ``seed``, a numeric string (``"1_0"`` was 10 ms, ``" 5 "`` was 5) and 1,500-deep JSON are each one
422 naming the field, like the other world routes, and the same keep-alive connection answers next. Before:
500 with a traceback and the next keep-alive request reset; the control server closed the connection
without a reply on the deep JSON."""

from __future__ import annotations

import http.client
import json
import socket
import sys
from collections.abc import Iterator

import pytest
from click.testing import CliRunner

from pywsg.cli.main import cli
from pywsg.server.netfault import NetFaults
from pywsg.testing import LoopThread, SimThread
from pywsg.testing.netcontrol import ControlServer

HUGE = "9" * 400
BAD_BODIES = [
    pytest.param(f'{{"kind": "latency", "ms": {HUGE}}}', "ms", id="huge-ms"),
    pytest.param(f'{{"kind": "latency", "ms": 5, "jitter": {HUGE}}}', "jitter", id="huge-jitter"),
    pytest.param(f'{{"kind": "drop", "p": {HUGE}}}', "p", id="huge-p"),
    pytest.param(f'{{"kind": "drop", "p": 0.5, "seed": {HUGE}}}', "seed", id="huge-seed"),
    pytest.param('{"kind": "latency", "ms": "1_0"}', "ms", id="string-1_0"),
    pytest.param('{"kind": "latency", "ms": " 5 "}', "ms", id="string-space-5"),
    pytest.param('{"kind": "bandwidth", "rate": 1e400}', "rate", id="1e400"),
    # Python 3.11/3.12 refuse the nesting itself ("_": not JSON); 3.13 parses it, and ms is then not a number
    pytest.param('{"kind": "latency", "ms": ' + "[" * 1500 + "]" * 1500 + "}",
                 "_" if sys.version_info < (3, 13) else "ms", id="1500-deep"),
]


@pytest.fixture(scope="module")
def sim() -> Iterator[SimThread]:
    with SimThread(clock="manual", web_port=0, tcp_port=0, udp_port=None) as s:
        yield s


@pytest.fixture(scope="module")
def control() -> Iterator[tuple[ControlServer, NetFaults]]:
    loop = LoopThread("control-inputs")
    net = NetFaults()
    server = ControlServer(net, loop.loop).start()
    try:
        yield server, net
    finally:
        server.close()
        loop.close()


def _exchange(port: int, body: str) -> tuple[int, dict[str, object], int]:
    """POST ``body`` to /api/world/net, then GET /api/world on the same keep-alive connection."""
    conn = http.client.HTTPConnection("127.0.0.1", port, timeout=10)
    try:
        conn.request("POST", "/api/world/net", body.encode(), {"Content-Type": "application/json"})
        r = conn.getresponse()
        status, reply = r.status, json.loads(r.read())
        conn.request("GET", "/api/world")
        r2 = conn.getresponse()
        r2.read()
        return status, reply, r2.status
    finally:
        conn.close()


@pytest.mark.parametrize(("body", "field"), BAD_BODIES)
def test_world_net_route_refuses_with_422_and_keeps_the_connection(sim: SimThread, body: str, field: str) -> None:
    port = sim.sim.grippers[0].web_port
    assert port
    status, reply, after = _exchange(port, body)
    assert (status, after) == (422, 200), reply
    assert field in reply["errors"], reply  # type: ignore[operator]
    assert sim.world.state()["net"] == {}


@pytest.mark.parametrize(("body", "field"), BAD_BODIES)
def test_proxy_control_refuses_with_422_and_keeps_the_connection(
        control: tuple[ControlServer, NetFaults], body: str, field: str) -> None:
    server, net = control
    status, reply, after = _exchange(server.port, body)
    assert (status, after) == (422, 200), reply
    assert field in reply["errors"], reply  # type: ignore[operator]
    assert net.state() == {}


def test_ordinary_numbers_still_work_on_both(sim: SimThread, control: tuple[ControlServer, NetFaults]) -> None:
    port = sim.sim.grippers[0].web_port
    assert port
    status, reply, _ = _exchange(port, '{"kind": "latency", "ms": 5, "jitter": 1.5, "seed": 7}')
    assert status == 200, reply
    sim.world.net("clear")
    server, net = control
    status, reply, _ = _exchange(server.port, '{"kind": "drop", "p": 0.25}')
    assert status == 200 and net.state() == {"drop": {"p": 0.25}}, reply
    net.clear()


def test_net_option_reads_numbers_and_refuses_numeric_look_alikes() -> None:
    """``--net`` is text: 200, 0.5 and 1e3 are numbers; 1_0 and nan are usage errors naming the field."""
    from pywsg.cli.proxy import start_fault

    net = NetFaults()
    start_fault(net, "latency:ms=200,jitter=0.5")
    start_fault(net, "bandwidth:rate=1e3")
    start_fault(net, "silent:on=off")
    assert net.state() == {"latency": {"ms": 200.0, "jitter": 0.5}, "bandwidth": {"rate": 1000.0}}
    for spec in ("latency:ms=1_0", "latency:ms=nan", f"drop:p=0.5,seed={HUGE}"):
        r = CliRunner().invoke(cli, ["proxy", "--listen", "0", "--to", "tcp://127.0.0.1:1", "--net", spec])
        assert r.exit_code == 2, (spec, r.output)
        assert "--net" in r.output and ("ms" in r.output or "seed" in r.output), r.output


@pytest.mark.parametrize("host", ["::1", "127.0.0.9"])
def test_control_on_ipv6_and_any_loopback_address_serves_wsg_world(host: str) -> None:
    """Issue 33 item 7: ``--control ::1:PORT`` failed (IPv4 only) and ``--control 127.0.0.9:PORT`` bound
    but refused every request (the Host check knew only 127.0.0.1, localhost and ::1)."""
    if ":" in host:
        try:
            socket.socket(socket.AF_INET6).close()
        except OSError:  # pragma: no cover - a machine without IPv6
            pytest.skip("no IPv6")
    loop = LoopThread("control-hosts")
    net = NetFaults()
    try:
        server = ControlServer(net, loop.loop, host, 0).start()
        try:
            r = CliRunner().invoke(cli, ["world", "--sim", server.url, "net", "latency", "--ms", "5"])
            assert r.exit_code == 0, r.output
            assert loop.call(net.state) == {"latency": {"ms": 5.0, "jitter": 0.0}}
        finally:
            server.close()
    finally:
        loop.close()
