"""`wsg sim` configured the container's way (docs/container.md): WSG_SIM_* variables, the web password from
the environment or a secret file, the refusal off loopback without one, GET /healthz without a login, and
RemoteWorld (the World methods over HTTP) against a running sim."""

from __future__ import annotations

import os
import subprocess
import time
import urllib.request
from collections.abc import Iterator
from pathlib import Path

import pytest
from click.testing import CliRunner

from pywsg.cli.main import cli
from pywsg.testing.remote import RemoteWorld, wait_healthy
from pywsg.testing.world import WorldError

from ..ports import free_base
from .conftest import WSG


@pytest.fixture(scope="module")
def env_sim(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[str, str]]:
    """A sim configured only by environment variables, its password in a file: (web URL, TCP URL)."""
    secret = tmp_path_factory.mktemp("secret") / "password"
    secret.write_text("from-the-file\nsecond line is not part of it\n")
    base = free_base(2)
    env = {k: v for k, v in os.environ.items() if k != "WSG_NO_ENV"}
    env.update(PYTHONUNBUFFERED="1", WSG_SIM_MODEL="wsg32", WSG_SIM_TCP_PORT=str(base), WSG_SIM_UDP_PORT="off",
               WSG_SIM_SERIAL_PORT="off", WSG_SIM_WEB_PORT=str(base + 1), WSG_WEB_PASSWORD_FILE=str(secret),
               WSG_SIM_REQUIRE_PASSWORD="1", WSG_SIM_UVLOOP="false")
    proc = subprocess.Popen([*WSG, "sim"], env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    web = f"http://127.0.0.1:{base + 1}"
    try:
        wait_healthy(web, timeout=30)
        yield web, f"tcp://127.0.0.1:{base}"
    finally:
        proc.terminate()
        proc.wait(timeout=15)


def test_environment_variables_configure_the_sim(env_sim: tuple[str, str]) -> None:
    web, _ = env_sim
    assert RemoteWorld(web, "from-the-file").state()["model"] == "wsg32"


def test_health_route_needs_no_login_and_says_nothing_else(env_sim: tuple[str, str]) -> None:
    web, _ = env_sim
    with urllib.request.urlopen(web + "/healthz", timeout=10) as reply:
        assert reply.status == 200 and reply.read() == b'{"status":"ok"}'
    with pytest.raises(WorldError, match="401"):   # the world API still wants the password
        RemoteWorld(web).state()


def test_remote_world_has_the_world_methods_and_their_refusals(env_sim: tuple[str, str]) -> None:
    from pywsg import Gripper
    from pywsg.protocol import GripperState

    web, url = env_sim
    world = RemoteWorld(web, "from-the-file")
    assert world.place_part(20.0) == "part of 20 mm placed (outside, between the fingers)"
    with Gripper(url, timeout=10) as g:
        g.home()
        g.grip(20.0, speed=200)
        assert g.gripper_state() == GripperState.HOLDING
    assert world.state()["gripper_state"] == "HOLDING"
    with pytest.raises(WorldError) as info:
        world.place_part(500.0)
    assert info.value.field == "width" and "stroke" in info.value.reason
    with pytest.raises(WorldError, match="401"):
        RemoteWorld(web, "wrong").state()
    with pytest.raises(RuntimeError, match="manual clock"):
        world.advance(1.0)
    assert world.manual is False
    world.remove_part()


def test_off_loopback_without_a_password_it_refuses_in_one_line() -> None:
    """Nothing is bound: the check comes before any socket."""
    env = {k: v for k, v in os.environ.items() if k != "WSG_NO_ENV"}
    env.update(WSG_SIM_HOST="0.0.0.0", WSG_SIM_REQUIRE_PASSWORD="1", WSG_SIM_SERIAL_PORT="off")
    env.pop("WSG_WEB_PASSWORD", None)
    t0 = time.monotonic()
    r = subprocess.run([*WSG, "sim"], env=env, capture_output=True, text=True, timeout=60)
    assert r.returncode == 1 and r.stdout == ""
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "WSG_WEB_PASSWORD" in lines[0] and "WSG_WEB_PASSWORD_FILE" in lines[0], lines
    assert time.monotonic() - t0 < 60


@pytest.mark.parametrize(("args", "text"), [
    (["--web-password", "a", "--web-password-file", "PATH"], "not both"),
    (["--web-password-file", "EMPTY"], "1..256 characters"),
    (["--web-password-file", "MISSING"], "cannot read"),
    (["--web-password", "x" * 257], "1..256 characters"),
])
def test_bad_passwords_are_usage_errors(tmp_path: Path, args: list[str], text: str) -> None:
    (tmp_path / "empty").write_text("")
    paths = {"PATH": str(tmp_path / "empty"), "EMPTY": str(tmp_path / "empty"), "MISSING": str(tmp_path / "nope")}
    args = [paths.get(a, a) for a in args]
    r = CliRunner().invoke(cli, ["sim", "--serial", "off", *args])
    assert r.exit_code == 2 and text in r.output, r.output
