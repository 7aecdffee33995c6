"""Network faults on `wsg proxy` in front of a gripper (issue 27 item 1): the Python API, `--net` at start
and `--control` switched at runtime with `wsg world`, and what pywsg's driver does behind it."""

from __future__ import annotations

import json
import signal
import socket
import subprocess
import time
from collections.abc import Iterator

import pytest

from pywsg.client import Gripper
from pywsg.errors import ConnectionLostError, TimeoutError
from pywsg.server.netfault import NetFaults
from pywsg.testing import LoopThread, SimThread
from pywsg.testing.proxy import Proxy

from .conftest import ENV, WSG, free_port, wsg


@pytest.fixture
def tapped() -> Iterator[tuple[SimThread, Proxy, LoopThread]]:
    """A sim (manual clock) and an in-process proxy in front of its TCP port."""
    loop = LoopThread("proxy-test")
    try:
        with SimThread(clock="manual", udp_port=0) as sim:
            proxy = Proxy(sim.url, net=NetFaults())
            loop.run(proxy.start())
            try:
                yield sim, proxy, loop
            finally:
                loop.run(proxy.close())
    finally:
        loop.close()


def _set(loop: LoopThread, proxy: Proxy, kind: str, **params: object) -> str:
    return loop.call(lambda: proxy.net.set(kind, params))


def test_proxy_latency_and_silence_reach_the_driver(tapped: tuple[SimThread, Proxy, LoopThread]) -> None:
    sim, proxy, loop = tapped
    with Gripper(proxy.address, timeout=2.0) as g:
        assert g.loop(b"through") == b"through"
        _set(loop, proxy, "latency", ms=120)
        t = time.monotonic()
        assert g.width() == 0.0
        assert time.monotonic() - t >= 0.11
        _set(loop, proxy, "latency", on=False)
        _set(loop, proxy, "silent")
        g.timeout = 0.1
        with pytest.raises(TimeoutError):
            g.temperature()
        assert proxy.net.counts["silenced"] > 0  # the request never reached the gripper
        assert sim.world.state()["fast_stop"] is False


def test_proxy_reset_gives_connection_lost(tapped: tuple[SimThread, Proxy, LoopThread]) -> None:
    sim, proxy, loop = tapped
    with Gripper(proxy.address, timeout=2.0) as g:
        g.loop(b"x")
        _set(loop, proxy, "reset", timeout=0)
        with pytest.raises(ConnectionLostError):
            g.loop(b"y")
    assert proxy.net.counts["reset"] == 1
    deadline = time.monotonic() + 5  # the proxy closed its gripper side: the sim saw no 07h
    while not sim.world.state()["fast_stop"] and time.monotonic() < deadline:
        time.sleep(0.01)
    assert sim.world.state()["fast_stop"]  # 000 §1.4.2


def test_wsg_proxy_net_and_control_switch_faults_at_runtime() -> None:
    with SimThread(udp_port=None) as sim:
        listen, control = free_port(), free_port()
        proc = subprocess.Popen([*WSG, "proxy", "-q", "--listen", str(listen), "--to", sim.url,
                                 "--net", "latency:ms=150", "--control", str(control)],
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=ENV)
        try:
            assert proc.stderr is not None
            lines = [proc.stderr.readline() for _ in range(3)]
            assert lines[0].startswith("proxy "), lines
            assert lines[1].startswith(f"control http://127.0.0.1:{control}"), lines
            assert "latency" in lines[2], lines
            base = f"http://127.0.0.1:{control}"
            with Gripper(f"tcp://127.0.0.1:{listen}", timeout=3.0) as g:
                t = time.monotonic()
                g.loop(b"slow")
                assert time.monotonic() - t >= 0.14
                done = wsg("world", "--sim", base, "net", "latency", "off")
                assert done.returncode == 0 and done.stdout.strip() == "latency off", done
                from click.testing import CliRunner

                from pywsg.cli.main import cli

                res = CliRunner().invoke(cli, ["world", "--sim", base, "net", "drop", "--ms", "3"])
                assert res.exit_code == 1 and "ms: not a parameter of drop" in res.output, res.output
                state = json.loads(CliRunner().invoke(cli, ["world", "--sim", base, "--json", "state"]).output)
                assert state["net"] == {}
                assert g.loop(b"fast") == b"fast"
        finally:
            proc.send_signal(signal.SIGINT)
            proc.communicate(timeout=15)


def test_wsg_proxy_refuses_a_bad_net_option_and_a_public_control_port() -> None:
    from click.testing import CliRunner

    from pywsg.cli.main import cli

    done = CliRunner().invoke(cli, ["proxy", "--listen", "0", "--to", "tcp://127.0.0.1:1", "--net", "latency:ms=-4"])
    assert done.exit_code == 2
    assert "--net" in done.output and "ms: must be within" in done.output
    done = CliRunner().invoke(cli, ["proxy", "--listen", "0", "--to", "tcp://127.0.0.1:1", "--control", "0.0.0.0:0"])
    assert done.exit_code == 2 and "loopback only" in done.output


def test_control_api_refuses_browser_pages_and_foreign_hosts(tapped: tuple[SimThread, Proxy, LoopThread]) -> None:
    from pywsg.testing.netcontrol import ControlServer

    _sim, proxy, loop = tapped
    server = ControlServer(proxy.net, loop.loop).start()
    try:
        def ask(headers: str) -> str:
            with socket.create_connection(("127.0.0.1", server.port), timeout=5) as s:
                s.sendall(f"GET /api/world HTTP/1.1\r\n{headers}Connection: close\r\n\r\n".encode())
                return s.recv(4096).decode("latin-1").split("\r\n", 1)[0]

        assert ask(f"Host: 127.0.0.1:{server.port}\r\n").endswith("200 OK")
        assert " 403 " in ask("Host: evil.example\r\n")
        assert " 403 " in ask(f"Host: 127.0.0.1:{server.port}\r\nOrigin: http://evil.example\r\n")
    finally:
        server.close()


def test_proxy_drops_udp_datagrams_in_front_of_the_gripper() -> None:
    loop = LoopThread("proxy-udp-test")
    try:
        with SimThread(clock="manual", tcp_port=None) as sim:
            proxy = Proxy(sim.udp_url, net=NetFaults())
            loop.run(proxy.start())
            try:
                with Gripper(proxy.address + "?reply_port=0", timeout=0.2) as g:
                    assert g.loop(b"through") == b"through"
                    _set(loop, proxy, "drop", p=1.0)
                    with pytest.raises(TimeoutError):
                        g.width()
                    assert proxy.net.counts["dropped"] >= 1
                    _set(loop, proxy, "drop", on=False)
                    assert g.temperature() > 0  # another command: in step at once
            finally:
                loop.run(proxy.close())
    finally:
        loop.close()
