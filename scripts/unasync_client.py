"""Generate the blocking driver's command methods from the asyncio ones (httpcore's unasync idea).

    python scripts/unasync_client.py          # rewrite src/pywsg/client/_sync/generated_commands.py
    python scripts/unasync_client.py --check  # exit 1 if it is out of date (the test suite runs this)

Source: ``src/pywsg/client/_async/commands.py``. Edit that file, then run this script.
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

CLIENT = Path(__file__).resolve().parents[1] / "src" / "pywsg" / "client"
SOURCE = CLIENT / "_async" / "commands.py"
TARGET = CLIENT / "_sync" / "generated_commands.py"

HEADER = '''"""GENERATED from ``pywsg/client/_async/commands.py`` by ``scripts/unasync_client.py`` - do not
edit; edit the source and run the script. The command methods of the blocking
:class:`~pywsg.client.Gripper`: :class:`Commands` (mixed into it) and :class:`Finger`.
"""
'''

# whole words only, longest first
SUBS = [
    ("AsyncCommands", "Commands"),
    ("AsyncFinger", "Finger"),
    ("AsyncMotion", "Motion"),
    ("AsyncGripper", "Gripper"),
    ("async def ", "def "),
    ("await ", ""),
]


def _realign(body: str) -> str:
    """A signature's continuation lines follow its opening parenthesis: 6 columns left with ``async``."""
    out: list[str] = []
    depth = 0  # open parentheses of an ``async def`` signature
    for line in body.splitlines(keepends=True):
        if depth:
            line = line[6:] if line.startswith(" " * 6) else line
        elif not line.lstrip().startswith("async def "):
            out.append(line)
            continue
        depth += line.count("(") - line.count(")")
        out.append(line)
    return "".join(out)


def unasync(text: str) -> str:
    body = _realign(text.split('"""', 2)[2].lstrip("\n"))  # without the source's module docstring
    for old, new in SUBS:
        body = re.sub(r"(?<![\w.])" + re.escape(old) if old[0].isalpha() else re.escape(old), new, body)
    return HEADER + "\n" + body


def main(argv: list[str]) -> int:
    new = unasync(SOURCE.read_text(encoding="utf-8"))
    if "--check" in argv:
        if not TARGET.exists() or TARGET.read_text(encoding="utf-8") != new:
            print(f"{TARGET} is out of date: run python scripts/unasync_client.py", file=sys.stderr)
            return 1
        return 0
    TARGET.write_text(new, encoding="utf-8")
    print(f"wrote {TARGET}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
