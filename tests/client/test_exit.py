"""Issue 16 item 1: a script that ends without ``close()`` announces the disconnect (07h, 000 §3.1.2)
at interpreter exit, so the gripper does not FAST STOP; a gripper garbage-collected open warns
(ResourceWarning) and announces too; a killed process still leaves FAST STOP (a lost connection,
1.4.2). Each test runs a real script in a subprocess against the sim in this process."""

from __future__ import annotations

import subprocess
import sys
import textwrap
import time

import pytest

from .conftest import SimThread


def run_script(body: str, *args: str, timeout: float = 30) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, *args, "-c", textwrap.dedent(body)], capture_output=True, text=True,
                          timeout=timeout)


def fast_stopped(sim: SimThread, wait: float = 1.0) -> bool:
    """The device's FAST STOP flag, once the sim has seen the connection close (polled up to ``wait`` s)."""
    deadline = time.monotonic() + wait
    while time.monotonic() < deadline:
        if sim.call(lambda: sim.device.fast_stopped):
            return True
        time.sleep(0.02)
    return False


def test_a_script_ending_without_close_announces_the_disconnect(sim: SimThread) -> None:
    url = sim.url("tcp")
    r = run_script(f"""
        from pywsg import Gripper
        g = Gripper({url!r})
        print(g.width())
        """, "-W", "default::ResourceWarning")
    assert r.returncode == 0, r.stderr
    assert "ResourceWarning" not in r.stderr, r.stderr  # closed at exit, not collected open
    float(r.stdout)
    assert not fast_stopped(sim)


def test_a_script_with_streams_running_at_exit_announces_too(sim: SimThread) -> None:
    url = sim.url("tcp")
    r = run_script(f"""
        from pywsg import Gripper
        g = Gripper({url!r})
        s = g.subscribe("width", 0.01)
        print(s.get(2).value)
        """, "-W", "default::ResourceWarning")
    assert r.returncode == 0, r.stderr
    assert "ResourceWarning" not in r.stderr, r.stderr  # closed at exit, not collected open
    assert not fast_stopped(sim)


def test_an_async_script_ending_without_close_announces_the_disconnect(sim: SimThread) -> None:
    url = sim.url("tcp")
    r = run_script(f"""
        import asyncio
        from pywsg import AsyncGripper
        async def main():
            global g
            g = await AsyncGripper.open({url!r})
            print(await g.width())
        asyncio.run(main())
        """, "-W", "default::ResourceWarning")
    assert r.returncode == 0, r.stderr
    # announced at exit, not at collection (asyncio itself may still note its socket: the loop is closed)
    assert "unclosed <AsyncGripper" not in r.stderr, r.stderr
    assert not fast_stopped(sim)


COLLECTED = {
    "Gripper": ('''
        from pywsg import Gripper
        print(Gripper(URL).width())  # the temporary is collected at once
        ''', "call close()"),
    "AsyncGripper": ('''
        import asyncio
        from pywsg import AsyncGripper
        async def main():
            return await (await AsyncGripper.open(URL)).width()
        loop = asyncio.new_event_loop()
        print(loop.run_until_complete(main()))
        loop.close()
        del loop  # the loop held the gripper (its protocol's callbacks): now it can be collected
        ''', "await close()"),
}


@pytest.mark.parametrize("cls", list(COLLECTED))
def test_a_gripper_collected_open_warns_and_announces(sim: SimThread, cls: str) -> None:
    body, advice = COLLECTED[cls]
    r = run_script(textwrap.dedent(body).replace("URL", repr(sim.url("tcp"))) + "import gc; gc.collect()\n",
                   "-W", "default::ResourceWarning")
    assert r.returncode == 0, r.stderr
    assert f"ResourceWarning: unclosed <{cls} tcp://" in r.stderr and advice in r.stderr
    assert not fast_stopped(sim)


def test_close_and_with_do_not_warn(sim: SimThread) -> None:
    url = sim.url("tcp")
    r = run_script(f"""
        from pywsg import Gripper
        with Gripper({url!r}) as g:
            g.width()
        g2 = Gripper({url!r})
        g2.close()
        del g, g2
        """, "-W", "error::ResourceWarning")
    assert r.returncode == 0 and "Warning" not in r.stderr, r.stderr
    assert not fast_stopped(sim)


def test_a_killed_script_still_leaves_fast_stop(sim: SimThread) -> None:
    """The rule is kept where it belongs: a process that dies announces nothing (os._exit skips
    atexit like SIGKILL does), the connection is lost, the gripper goes to FAST STOP."""
    url = sim.url("tcp")
    r = run_script(f"""
        import os
        from pywsg import Gripper
        g = Gripper({url!r})
        print(g.width(), flush=True)
        os._exit(0)
        """)
    assert r.returncode == 0, r.stderr
    assert fast_stopped(sim, wait=5)


def test_a_forked_child_does_not_announce_the_parents_gripper(sim: SimThread) -> None:
    """A child inherits the open gripper (and its socket) through fork; its exit must not end the
    parent's session with a 07h of its own."""
    url = sim.url("tcp")
    r = run_script(f"""
        import os, sys
        from pywsg import Gripper
        g = Gripper({url!r})
        g.width()
        pid = os.fork()
        if pid == 0:
            sys.exit(0)                          # a clean exit: atexit and collection run in the child
        os.waitpid(pid, 0)
        g.home()                                 # the parent's session goes on
        print("parent ok", g.width())
        g.close()
        """, "-W", "default::ResourceWarning")
    assert r.returncode == 0 and "parent ok" in r.stdout, r.stderr
    assert "unclosed <Gripper" not in r.stderr, r.stderr  # the child leaves the gripper alone
    assert not fast_stopped(sim)
