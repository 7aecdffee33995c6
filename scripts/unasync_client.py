"""Generate the blocking driver's command methods and lifecycle flows from the asyncio ones (httpcore's unasync idea).

    python scripts/unasync_client.py          # rewrite src/pywsg/client/_sync/generated_*.py
    python scripts/unasync_client.py --check  # exit 1 if one is out of date (the test suite runs this)

Sources: ``src/pywsg/client/_async/commands.py`` (the command methods) and ``lifecycle.py`` (reconnect,
error reports, ``request()``). Edit those files, then run this script.
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

CLIENT = Path(__file__).resolve().parents[1] / "src" / "pywsg" / "client"

# source in _async/ -> (target in _sync/, what the target holds)
FILES = {
    "commands.py": ("generated_commands.py", "The command methods of the blocking\n"
                    ":class:`~pywsg.client.Gripper`: :class:`Commands` (mixed into it) and :class:`Finger`."),
    "lifecycle.py": ("generated_lifecycle.py", "Reconnection, error reports and raw requests of the\n"
                     "blocking :class:`~pywsg.client.Gripper`: :class:`Lifecycle` (mixed into it)."),
}

HEADER = '''"""GENERATED from ``pywsg/client/_async/{source}`` by ``scripts/unasync_client.py`` - do not
edit; edit the source and run the script. {what}
"""
'''

# whole words only, longest first
SUBS = [
    ("AsyncCommands", "Commands"),
    ("AsyncLifecycle", "Lifecycle"),
    ("AsyncStream", "Stream"),
    (", AWaiter\n", "\n"),  # the import: the blocking shell's waiter is demux.Waiter itself
    ("AWaiter", "Waiter"),
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


def unasync(text: str, source: str = "commands.py", what: str = FILES["commands.py"][1]) -> str:
    body = _realign(text.split('"""', 2)[2].lstrip("\n"))  # without the source's module docstring
    for old, new in SUBS:
        body = re.sub(r"(?<![\w.])" + re.escape(old) if old[0].isalpha() else re.escape(old), new, body)
    return HEADER.format(source=source, what=what) + "\n" + body


def main(argv: list[str]) -> int:
    stale = 0
    for source, (target, what) in FILES.items():
        new = unasync((CLIENT / "_async" / source).read_text(encoding="utf-8"), source, what)
        path = CLIENT / "_sync" / target
        if "--check" in argv:
            if not path.exists() or path.read_text(encoding="utf-8") != new:
                print(f"{path} is out of date: run python scripts/unasync_client.py", file=sys.stderr)
                stale += 1
            continue
        path.write_text(new, encoding="utf-8")
        print(f"wrote {path}")
    return 1 if stale else 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
