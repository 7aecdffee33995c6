"""`wsg send` and `wsg log` over CAN (inferred mapping, docs/driver.md "CAN"; 000 §1.1 names CAN as an
interface): the CLI in-process (python-can's ``virtual`` bus connects only threads of one process)
against the sim's CAN side, through the driver's CAN transport."""

from __future__ import annotations

import json
import uuid
from collections.abc import Iterator

import pytest
from click.testing import CliRunner

from pywsg.cli.main import cli

from ..client.conftest import SimThread
from ..simthread import started

can = pytest.importorskip("can")


@pytest.fixture
def can_url() -> Iterator[str]:
    gen = started(SimThread)
    make = next(gen)
    ch = f"wsg-{uuid.uuid4().hex[:8]}"
    make(tcp_port=None, udp_port=None, serial=None, can_channel=ch)
    yield f"can://{ch}?interface=virtual"
    next(gen, None)


def test_send_over_can_gets_the_reply(can_url: str) -> None:
    r = CliRunner().invoke(cli, ["--url", can_url, "send", "get-system-info"])
    assert r.exit_code == 0, r.output
    assert "type=WSG50 (1)" in r.output


def test_send_over_can_a_motion_shows_pending_and_result(can_url: str) -> None:
    r = CliRunner().invoke(cli, ["--url", can_url, "send", "--json", "homing", "0"])
    assert r.exit_code == 0, r.output
    statuses = [x["status"] for x in json.loads(r.output)["replies"]]
    assert statuses[:2] == ["E_CMD_PENDING", "E_SUCCESS"], statuses


def test_log_over_can_shows_subscribed_auto_updates(can_url: str) -> None:
    r = CliRunner().invoke(cli, ["--url", can_url, "log", "--subscribe", "width", "--period", "20",
                                 "--duration", "0.5", "--json"])
    assert r.exit_code == 0, r.output
    rx = [json.loads(line) for line in r.output.splitlines() if line.startswith("{")]
    widths = [x for x in rx if x.get("direction") == "rx" and x.get("command") == "GET_OPENING_WIDTH"]
    assert len(widths) >= 3, r.output


def test_send_to_a_missing_can_channel_is_a_connection_error() -> None:
    r = CliRunner().invoke(cli, ["--url", "can://nope?interface=nosuchinterface", "send", "0x50"])
    assert r.exit_code == 3 and "cannot open" in r.output, r.output


def test_send_over_can_on_other_identifiers(sim_ids: str) -> None:
    """A sim on request 0x10 / reply 0x11 answers a URL with the same request_id / reply_id."""
    r = CliRunner().invoke(cli, ["--url", sim_ids, "send", "get-system-info"])
    assert r.exit_code == 0, r.output
    assert "type=WSG50 (1)" in r.output


@pytest.fixture
def sim_ids() -> Iterator[str]:
    gen = started(SimThread)
    make = next(gen)
    ch = f"wsg-{uuid.uuid4().hex[:8]}"
    st = make(tcp_port=None, udp_port=None, serial=None, can_channel=ch, can_rx_id=0x10, can_tx_id=0x11)
    url = st.sim.grippers[0].can.address  # the URL `wsg sim` prints: a client connects with it as it is
    assert url == f"can://{ch}?interface=virtual&request_id=0x10&reply_id=0x11"
    yield url
    next(gen, None)


def test_wsg_sim_can_options_reach_the_sim(monkeypatch: pytest.MonkeyPatch) -> None:
    """`wsg sim --can-rx-id/--can-tx-id/--can-bitrate` become the SimOptions the CAN side is built from."""
    import pywsg.server.sim as sim_mod

    seen: list[sim_mod.SimOptions] = []

    async def fake_run_sim(options: sim_mod.SimOptions, **_: object) -> None:
        seen.append(options)

    monkeypatch.setattr(sim_mod, "run_sim", fake_run_sim)
    r = CliRunner().invoke(cli, ["sim", "--no-uvloop", "--can", "can0", "--can-interface", "socketcan",
                                 "--can-rx-id", "0x10", "--can-tx-id", "17", "--can-bitrate", "1000000"])
    assert r.exit_code == 0, r.output
    (o,) = seen
    assert (o.can_channel, o.can_interface, o.can_rx_id, o.can_tx_id, o.can_bitrate) == \
        ("can0", "socketcan", 0x10, 0x11, 1_000_000)


@pytest.mark.parametrize(("args", "words"), [
    (["--can-rx-id", "0x800"], "not an 11-bit CAN identifier"),
    (["--can-tx-id", "x"], "not an integer"),
    (["--can-rx-id", "5", "--can-tx-id", "5"], "need their own identifiers"),
])
def test_wsg_sim_refuses_bad_can_identifiers(args: list[str], words: str) -> None:
    r = CliRunner().invoke(cli, ["sim", "--can", "can0", *args])
    assert r.exit_code == 2 and words in r.output, r.output
