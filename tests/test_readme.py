"""The README's Python quick start runs as written against a virtual gripper (only the port differs)."""

from __future__ import annotations

import asyncio
import contextlib
import io
import re
import threading
from pathlib import Path

from pywsg.server import SimServer

README = Path(__file__).resolve().parents[1] / "README.md"


def test_readme_python_quick_start_runs() -> None:
    blocks = re.findall(r"```python\n(.*?)```", README.read_text(encoding="utf-8"), re.S)
    assert blocks, "README has no Python example"
    ready = threading.Event()
    stop: asyncio.Event | None = None
    url: list[str] = []
    loop = asyncio.new_event_loop()

    async def serve() -> None:
        nonlocal stop
        stop = asyncio.Event()
        async with SimServer(tcp_port=0, udp_port=None) as sim:
            url.append(str(sim.grippers[0].tcp_url))
            ready.set()
            await stop.wait()

    t = threading.Thread(target=loop.run_until_complete, args=(serve(),), daemon=True)
    t.start()
    assert ready.wait(10)
    try:
        code = blocks[0].replace("tcp://127.0.0.1:1000", url[0])
        out = io.StringIO()
        with contextlib.redirect_stdout(out):
            exec(compile(code, "README.md", "exec"), {})
        text = out.getvalue()
        # no part placed: the example takes its NoPartError branch and prints what its comment says
        said = re.search(r"print\(exc\.status, exc\.flags\)\s+# (.+)", blocks[0])
        assert said is not None
        assert text.splitlines()[0] == said.group(1).strip()  # names, not 262145 (issue 16 item 6)
        assert "NO_PART" in text
    finally:
        assert stop is not None
        loop.call_soon_threadsafe(stop.set)
        t.join(10)
