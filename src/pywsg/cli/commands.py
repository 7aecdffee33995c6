"""The commander's subcommands (issue 5), looked up by ``wsg`` through :data:`COMMANDS`.

Only click (and the light protocol tables) are imported here; each command imports the driver,
rich or dpkt when it runs, so ``wsg --help`` and shell completion stay fast.
"""

from __future__ import annotations

import click

from .gripper import GRIPPER_COMMANDS
from .logcmd import log_cmd
from .monitor import monitor
from .send import send

COMMANDS: dict[str, click.Command] = {
    **GRIPPER_COMMANDS,
    "send": send,
    "log": log_cmd,
    "monitor": monitor,
}
