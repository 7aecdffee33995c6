"""The Commander page (000 §2) in real headless Chromium against ``wsg sim`` over TCP, UDP, a serial pty and CAN.

Connect through the dialog; the Custom Command Editor decodes as one types, marks a bad item at its
place, and the packet it shows is byte-equal to what reaches the sim; the Communication Log streams
both directions and converts selected bytes; a motion shows live and Escape stops it (000 §3.2.3);
keyboard only at phone width; a lost connection shows at once; closing the page sends 07h (000
§3.1.2); axe-core finds no WCAG A/AA violation at phone and desktop width.
"""

from __future__ import annotations

import uuid
from collections.abc import Iterator
from typing import Any

import pytest

from pywsg.testing.host import SimThread

from ..conftest import wait_for
from .harness import Cmdr, WireTap

pytestmark = pytest.mark.browser

PHONE = {"width": 390, "height": 844}
DESKTOP = {"width": 1400, "height": 950}


@pytest.fixture(scope="module")
def sim() -> Iterator[SimThread]:
    channel = f"cmdr-{uuid.uuid4().hex[:8]}"  # python-can's virtual channels are process-global
    with SimThread(model="wsg50", tcp_port=0, udp_port=0, udp_reply_port=None, can_channel=channel) as s:
        yield s


@pytest.fixture(scope="module")
def tap(sim: SimThread) -> WireTap:
    return WireTap(sim)


@pytest.fixture(scope="module")
def cmdr() -> Iterator[Cmdr]:
    with Cmdr(grace=0.3) as c:
        yield c


def connect(page: Any, cmdr: Cmdr, iface: str, **fields: str) -> None:
    """Gripper → Connect through the dialog: the interface, its fields, Connect."""
    page.goto(cmdr.url + "/")
    page.click("#btn-connect")
    page.check(f"input[name=iface][value={iface}]")
    for field, value in fields.items():
        page.fill(f"#cd-{field}", value)
    page.click("#cd-connect")
    page.wait_for_selector("#connect-dialog", state="hidden")  # closed on the connect's answer
    page.wait_for_selector("#c-dot.on")


def links(sim: SimThread) -> dict[str, tuple[str, dict[str, str]]]:
    return {
        "tcp": ("tcp", {"host": "127.0.0.1", "port": str(sim.g.tcp_port)}),
        "udp": ("udp", {"host": "127.0.0.1", "port": str(sim.g.udp_port), "reply": "0"}),
        "serial": ("serial", {"device": sim.serial_url.split("://", 1)[1].split("?")[0]}),
        "can": ("can", {"channel": sim.g.can.address.split("://", 1)[1].split("?")[0], "interface": "virtual",
                        "bitrate": "0"}),
    }


@pytest.mark.parametrize("link", ["tcp", "udp", "serial", "can"])
def test_editor_packet_shown_is_what_reaches_the_sim(sim: SimThread, tap: WireTap, cmdr: Cmdr, open_page: Any,
                                                     link: str) -> None:
    page = open_page(DESKTOP)
    iface, fields = links(sim)[link]
    connect(page, cmdr, iface, **fields)
    assert cmdr.state()["connection"]["url"].startswith(link)
    page.fill("#ed-id", "loop")
    page.fill("#ed-payload", '0x12 52 150.0f "ok" 1000u16')
    # decoded live as typed: preamble, ID, size, the items, the CRC (000 §1.2.1)
    page.wait_for_function("document.getElementById('ed-packet').dataset.wire"
                           " && document.getElementById('ed-packet').dataset.wire.startsWith('AA AA AA 06 0A 00')")
    shown = page.get_attribute("#ed-packet", "data-wire")
    assert page.locator("#ed-packet .item").all_inner_texts() == ["12", "34", "00 00 16 43", "6F 6B", "E8 03"]
    tap.clear()
    page.click("#ed-send")
    page.wait_for_selector(f"#log-body tr.tx[data-hex='{shown}']")
    page.wait_for_selector("#log-body tr.rx td:has-text('LOOP')")
    assert bytes.fromhex(shown) in tap.data, (shown, tap.data.hex(" "))
    page.wait_for_function("document.getElementById('ed-result').textContent.includes('E_SUCCESS')")


def test_editor_marks_the_bad_item_and_will_not_send(cmdr: Cmdr, open_page: Any) -> None:
    page = open_page(DESKTOP)
    page.goto(cmdr.url + "/")
    page.fill("#ed-payload", "1 2 300 4")
    page.wait_for_selector("#ed-payload[aria-invalid=true]")
    assert page.inner_text("#ed-echo mark") == "300"
    assert "a decimal item is one byte" in page.inner_text("#ed-error")
    assert page.is_disabled("#ed-send")
    page.fill("#ed-payload", "1 2 3 4")
    page.wait_for_function("!document.getElementById('ed-send').disabled")
    assert page.inner_text("#ed-echo") == "" and page.get_attribute("#ed-payload", "aria-invalid") is None


def test_phone_by_keyboard_motion_live_escape_stops_and_bytes_convert(sim: SimThread, cmdr: Cmdr,
                                                                       open_page: Any) -> None:
    page = open_page(PHONE)
    connect(page, cmdr, "tcp", host="127.0.0.1", port=str(sim.g.tcp_port))
    r = cmdr.http.post("/api/command/home", json={})
    assert r.status_code == 202, r.text
    wait_for(lambda: cmdr.state()["state"].get("referenced") is True and not cmdr.state()["state"].get("moving"))
    # the first Tab stop leads to Stop
    page.reload()  # the connection stays (a reload is no close)
    page.wait_for_selector("#c-dot.on")
    page.keyboard.press("Tab")
    assert page.evaluate("document.activeElement.id") == "skip-stop"
    page.keyboard.press("Enter")
    assert page.evaluate("document.activeElement.id") == "c-stop"
    # choose 21h by typing in the select, fill width and speed, Enter sends
    page.focus("#cmd-select")
    page.keyboard.type("21h")
    assert page.input_value("#cmd-select") == "move"
    page.keyboard.press("Tab")
    assert page.evaluate("document.activeElement.id") == "p-width"
    page.keyboard.press("Control+A")
    page.keyboard.type("5")
    page.keyboard.press("Tab")
    page.keyboard.press("Control+A")
    page.keyboard.type("10")
    page.keyboard.press("Enter")
    page.wait_for_function("document.getElementById('s-state').textContent === 'POSITIONING'")  # live, streamed
    first = page.inner_text("#s-width")
    page.wait_for_function(f"document.getElementById('s-width').textContent !== '{first}'")
    page.keyboard.press("Escape")  # Stop from anywhere (22h)
    page.wait_for_function("document.getElementById('cmd-result').textContent.includes('E_CMD_ABORTED')")
    assert page.inner_text("#c-stop-result").startswith("STOP: E_SUCCESS")
    # bytes selected in the log, shown as integers, float32 and text
    page.evaluate("""() => {
      const row = [...document.querySelectorAll('#log-body tr.tx')].find(r => r.cells[3].textContent === 'PREPOSITION');
      const cell = row.cells[4].firstChild;            // AA AA AA 21 09 00 FLAGS WIDTH(4) SPEED(4) CRC(2)
      const range = document.createRange();
      range.setStart(cell, 7 * 3); range.setEnd(cell, 7 * 3 + 11);   // the width: 00 00 A0 40
      getSelection().removeAllRanges(); getSelection().addRange(range);
    }""")
    page.wait_for_function("document.getElementById('cv-f').textContent === '5'")
    assert page.input_value("#conv-bytes") == "00 00 A0 40"
    assert page.inner_text("#cv-32") == "1084227584 / 1084227584"
    # by keyboard: Enter on a log line shows its parameters
    page.focus("#log-body tr.rx:has(td:text-is('GET_OPENING_WIDTH'))")
    page.keyboard.press("Enter")
    assert page.evaluate("document.activeElement.id") == "conv-bytes"
    assert len(page.input_value("#conv-bytes").split()) == 4


def test_lost_connection_shows_at_once_and_closing_sends_07h(sim: SimThread, tap: WireTap, cmdr: Cmdr,
                                                             open_page: Any) -> None:
    page = open_page(DESKTOP)
    connect(page, cmdr, "tcp", host="127.0.0.1", port=str(sim.g.tcp_port))
    sim.world.disconnect()
    try:
        page.wait_for_function("document.getElementById('banner').textContent.includes('lost')", timeout=5000)
        assert "CONNECTION LOST" in page.inner_text("#c-conn")
    finally:
        sim.call(sim.gripper.acknowledge_fast_stop)
    connect(page, cmdr, "tcp", host="127.0.0.1", port=str(sim.g.tcp_port))
    tap.clear()
    page.context.close()  # the user closes the tab
    wait_for(lambda: cmdr.state()["connection"]["status"] == "disconnected", 10)
    assert bytes.fromhex("AA AA AA 07 00 00") in tap.data
    assert not sim.call(lambda: sim.gripper.snapshot().fast_stop)
