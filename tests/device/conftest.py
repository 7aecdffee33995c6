"""Fixtures for the virtual gripper tests.

Every device test also checks that the catalog tells the truth (issue 12 item 9): each status the
firmware answers a command with — immediate or final — must be in that command's status list in
``pywsg.protocol.catalog`` (and so in the generated docs/commands.md).
"""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from pywsg.device import VirtualGripper
from pywsg.device.core import DeviceCore
from pywsg.protocol import CATALOG, Frame, Status

from .devrig import Rig, make_rig


@pytest.fixture(autouse=True)
def statuses_agree_with_the_catalog(monkeypatch: pytest.MonkeyPatch) -> Iterator[None]:
    wrong: list[str] = []

    def check(cid: int, status: int) -> None:
        spec = CATALOG.get(cid)
        if spec is not None and status not in spec.statuses:
            wrong.append(f"{cid:02X}h answered {Status.describe(status)}, not in the catalog's list")

    handle_frame = VirtualGripper.handle_frame
    final_reply = DeviceCore.final_reply

    def checked_handle_frame(self: VirtualGripper, s: object, frame: Frame) -> list[Frame]:
        refused = getattr(s, "denied", False) or getattr(s, "announced", False) or getattr(s, "closed", False)
        replies = handle_frame(self, s, frame)  # type: ignore[arg-type]
        if not refused and replies:  # a refused session gets E_ACCESS_DENIED for anything (000 §2.x)
            check(frame.command_id, replies[-1].status)
        return replies

    def checked_final_reply(self: DeviceCore, motion: object, status: Status) -> None:
        check(getattr(motion, "command_id", 0) or 0, status)
        final_reply(self, motion, status)  # type: ignore[arg-type]

    monkeypatch.setattr(VirtualGripper, "handle_frame", checked_handle_frame)
    monkeypatch.setattr(DeviceCore, "final_reply", checked_final_reply)
    yield
    assert not wrong, wrong


@pytest.fixture
def rig() -> Iterator[Rig]:
    yield make_rig()


@pytest.fixture
def homed(rig: Rig) -> Rig:
    rig.home()
    return rig
