"""Every code block of README.md and docs/*.md runs as written against a plain `wsg sim`.

The rules, for whoever writes docs:

* ```` ```python ```` blocks run as scripts (top-level ``await`` allowed), ```` ```sh ```` blocks run in
  ``bash -e`` with the venv's ``wsg`` first on PATH, one block after the other in the order of the page,
  against one ``wsg sim`` per page started the way the docs start it (defaults: no part between the
  fingers, not referenced at first), like a reader following along in a second terminal.
* Pages run at once (one thread, sim and directory each); the blocks of a page one after the other.
* The sim runs on free ports, so the harness rewrites the default ones in each block:
  ``tcp://127.0.0.1:1000``, ``udp://127.0.0.1:1500`` (replies to 1501), the web port 8080 and the
  Modbus port 5020; ``wsg proxy --listen 2000`` (and ``127.0.0.1:2000``) gets a free port too.
  ``WSG_URL`` points at the sim's TCP interface, ``WSG_SIM`` at its web address.
  Lines that start ``wsg sim`` are dropped from sh blocks: that sim is the one already running.
* ```` ```text ```` blocks are output or syntax shown to the reader and never run. Every other block
  needs a language, and a block that must not run (a real gripper's address, an endless server, an API
  summary) is marked on the line just before it with ``<!-- not-run: the reason -->``; the reason is
  required, and it is what the reader would want to know anyway.
* The docs stand alone: no references to files outside the repository (``SPEC-NOTES``, ``../shared``).

A failure names the file and line of the block, shows the block as it ran and the tail of its output.
"""

from __future__ import annotations

import json
import os
import re
import signal
import socket
import subprocess
import sys
import textwrap
from collections.abc import Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import pytest

from .cli.conftest import free_port

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
BIN = Path(sys.executable).parent
RUN_PY = {"python", "py", "python3"}
RUN_SH = {"sh", "bash", "shell"}
SHOWN = {"text"}
FENCE = re.compile(r"^(?P<indent> {0,3})(?P<fence>`{3,}|~{3,})(?P<lang>[^`\s]*)[^`]*$")
NOT_RUN = re.compile(r"^\s*<!--\s*not-run:(?P<reason>.*?)-->\s*$")
BLOCK_TIMEOUT = 240.0  # s per block: a hang guard, generous for a loaded machine

PY_RUNNER = """
import ast, asyncio, inspect, sys, types
path = sys.argv[1]
code = compile(open(path, encoding="utf-8").read(), path, "exec", flags=ast.PyCF_ALLOW_TOP_LEVEL_AWAIT)
namespace = {"__name__": "__main__"}
if code.co_flags & inspect.CO_COROUTINE:
    asyncio.run(types.FunctionType(code, namespace)())
else:
    exec(code, namespace)
"""


@dataclass
class Block:
    page: Path
    line: int  # 1-based line of the opening fence
    lang: str
    code: str
    not_run: str | None  # the reason, when marked

    @property
    def where(self) -> str:
        return f"{self.page.relative_to(ROOT)}:{self.line}"


def blocks_of(page: Path) -> list[Block]:
    """The fenced code blocks of ``page``, each with its language and its not-run marker."""
    out: list[Block] = []
    lines = page.read_text(encoding="utf-8").splitlines()
    i = 0
    last_text = ""  # the last non-blank line before a fence
    while i < len(lines):
        m = FENCE.match(lines[i])
        if m is None:
            if lines[i].strip():
                last_text = lines[i]
            i += 1
            continue
        fence, start = m["fence"], i
        body: list[str] = []
        i += 1
        while i < len(lines) and not lines[i].strip().startswith(fence):
            body.append(lines[i][len(m["indent"]):])
            i += 1
        marker = NOT_RUN.match(last_text)
        out.append(Block(page, start + 1, m["lang"].lower(), "\n".join(body) + "\n",
                         marker["reason"].strip() if marker else None))
        last_text = ""
        i += 1
    return out


class PageSim:
    """One `wsg sim` for a page, as the docs start it, on free ports."""

    def __init__(self) -> None:
        self.reply_port = free_port(socket.SOCK_DGRAM)
        self.proxy_port = free_port()  # the docs' `wsg proxy --listen 2000`
        argv = [str(BIN / "wsg"), "sim", "--json", "--no-uvloop", "--tcp-port", "0", "--udp-port", "0",
                "--udp-reply-port", str(self.reply_port), "--serial", "off", "--web-port", "0",
                "--modbus-port", "0"]
        self.proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        assert self.proc.stdout is not None
        self.urls: dict[str, str] = {}
        while len(self.urls) < 4:
            line = self.proc.stdout.readline()
            if not line:
                raise RuntimeError(f"wsg sim exited: {self.proc.stderr.read() if self.proc.stderr else ''}")
            event = json.loads(line)
            if event.get("event") == "interface":
                self.urls[event["kind"]] = event["url"]

    def port(self, kind: str) -> int:
        return int(re.findall(r":(\d+)", self.urls[kind])[-1])

    def rewrite(self, code: str) -> str:
        """The block with the documented default ports replaced by this sim's."""
        tcp, udp = self.port("tcp"), self.port("udp")

        def udp_url(m: re.Match[str]) -> str:
            query = m["query"] or ""
            if "reply_port=1501" in query:
                query = query.replace("reply_port=1501", f"reply_port={self.reply_port}")
            elif "reply_port=" not in query:
                query = f"{query}&reply_port={self.reply_port}" if query else f"?reply_port={self.reply_port}"
            return f"udp://{m['host']}:{udp}{query}"

        code = re.sub(r"tcp://(127\.0\.0\.1|localhost):1000\b", rf"tcp://\1:{tcp}", code)
        code = re.sub(r"udp://(?P<host>127\.0\.0\.1|localhost):1500(?P<query>\?[^\s\"'`)]*)?", udp_url, code)
        code = re.sub(r"(--listen |127\.0\.0\.1:)2000\b", rf"\g<1>{self.proxy_port}", code)  # wsg proxy
        code = re.sub(r"\b5020\b", str(self.port("modbus")), code)
        code = re.sub(r"\b8080\b", str(self.port("web")), code)
        return code.replace(".venv/bin/", f"{BIN}/")

    def stop(self) -> None:
        self.proc.terminate()
        try:
            self.proc.wait(15)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()


def _numbered(code: str) -> str:
    return "\n".join(f"{n:3} | {line}" for n, line in enumerate(code.rstrip("\n").splitlines(), 1))


def _tail(text: str, lines: int = 25) -> str:
    return "\n".join(text.rstrip().splitlines()[-lines:]) or "(nothing)"


def run_block(block: Block, sim: PageSim, workdir: Path) -> str | None:
    """Run one block; None when it worked, else a readable report."""
    code = sim.rewrite(block.code)
    env = {**os.environ, "WSG_URL": sim.urls["tcp"], "WSG_SIM": sim.urls["web"], "COLUMNS": "120",
           "NO_COLOR": "1", "PYTHONUNBUFFERED": "1", "PATH": f"{BIN}{os.pathsep}{os.environ.get('PATH', '')}"}
    if block.lang in RUN_PY:
        script = workdir / f"block_{block.line}.py"
        script.write_text(code, encoding="utf-8")
        argv = [sys.executable, "-c", PY_RUNNER, str(script)]
    else:
        code = "\n".join(": # harness: that wsg sim is already running" if re.match(
            r"\s*(\S*/)?wsg\s+sim\b", line) else line for line in code.splitlines()) + "\n"
        argv = ["bash", "-e", "-o", "pipefail", "-c", code]
    # Output goes to files, not pipes, and the block runs in its own session: when the block ends, whatever
    # it left running in the background (a `wsg proxy &` of a failed block) is ended with it instead of
    # holding a pipe open until the timeout.
    out_path, err_path = workdir / f"block_{block.line}.out", workdir / f"block_{block.line}.err"
    with out_path.open("w") as out_f, err_path.open("w") as err_f:
        proc = subprocess.Popen(argv, stdout=out_f, stderr=err_f, env=env, cwd=workdir, stdin=subprocess.DEVNULL,
                                start_new_session=True)
        try:
            returncode: int | None = proc.wait(BLOCK_TIMEOUT)
        except subprocess.TimeoutExpired:
            returncode = None
        finally:
            try:
                os.killpg(proc.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
            proc.wait()
    stdout, stderr = out_path.read_text(errors="replace"), err_path.read_text(errors="replace")
    if returncode is None:
        return (f"{block.where}: ```{block.lang} block still running after {BLOCK_TIMEOUT:g} s\n"
                f"--- block as run ---\n{_numbered(code)}\n--- stdout ---\n{_tail(stdout)}")
    if returncode == 0:
        return None
    return (f"{block.where}: ```{block.lang} block failed (exit {returncode})\n"
            f"--- block as run ---\n{_numbered(code)}\n"
            f"--- stdout ---\n{_tail(stdout)}\n--- stderr ---\n{_tail(stderr)}\n"
            "Fix the example, or mark it <!-- not-run: reason --> on the line before if it is an illustration.")


def _ids(page: Path) -> str:
    return str(page.relative_to(ROOT))


def _workdir(tmp_path: Path) -> Path:
    """Where blocks run: a scratch directory that sees the checkout's docs/ and scripts/."""
    for name in ("docs", "scripts"):
        (tmp_path / name).symlink_to(ROOT / name)
    return tmp_path


def run_page(page: Path, workdir: Path) -> tuple[int, list[str]]:
    """Run the page's blocks in order against its own sim: (blocks run, failure reports)."""
    runnable = [b for b in blocks_of(page) if b.not_run is None and b.lang in RUN_PY | RUN_SH]
    sim = PageSim()
    try:
        return len(runnable), [f for b in runnable if (f := run_block(b, sim, workdir)) is not None]
    finally:
        sim.stop()


RUN_PAGES = [p for p in PAGES if any(b.not_run is None and b.lang in RUN_PY | RUN_SH for b in blocks_of(p))]


@pytest.mark.parametrize("page", PAGES, ids=_ids)
def test_every_block_has_a_language_or_a_reason(page: Path) -> None:
    problems = []
    for b in blocks_of(page):
        if b.not_run is not None and not b.not_run:
            problems.append(f"{b.where}: <!-- not-run: --> needs a reason the reader can see")
        elif b.not_run is None and b.lang not in RUN_PY | RUN_SH | SHOWN:
            what = f"```{b.lang}" if b.lang else "an untagged block"
            problems.append(f"{b.where}: {what} is neither run nor marked: tag it ```python or ```sh (run), "
                            "```text (output shown, never run), or put <!-- not-run: reason --> before it\n"
                            + textwrap.indent(_tail(b.code, 4), "    "))
    assert not problems, "\n\n".join(problems)


@pytest.mark.parametrize("page", PAGES, ids=_ids)
def test_docs_stand_alone(page: Path) -> None:
    """Cite the manuals (000..003 with § numbers) and docs/fidelity.md, not files outside the repository."""
    text = page.read_text(encoding="utf-8")
    found = [f"{_ids(page)}:{n}: {line.strip()}" for n, line in enumerate(text.splitlines(), 1)
             if re.search(r"SPEC-NOTES|\.\./shared|/work/shared", line)]
    assert not found, "references to files that are not in the repository:\n" + "\n".join(found)


@pytest.fixture(scope="module")
def page_runs(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory
              ) -> Iterator[dict[Path, Future[tuple[int, list[str]]]]]:
    """The selected pages all run at once, each in its own thread with its own sim and directory.

    The blocks mostly wait on motion in real time (a homing, a move at 100 mm/s, a demo cycle), not on
    the CPU, so the pages overlap instead of queueing: the slowest page sets the time, not their sum.
    Within a page the blocks still run one after the other, as a reader runs them.
    """
    selected = [p for p in RUN_PAGES if any(
        item.originalname == "test_examples_run_as_written" and item.callspec.params.get("page") == p
        for item in request.session.items if isinstance(item, pytest.Function) and hasattr(item, "callspec"))]
    with ThreadPoolExecutor(max_workers=max(1, len(selected))) as pool:
        yield {p: pool.submit(run_page, p, _workdir(tmp_path_factory.mktemp(p.stem))) for p in selected}


@pytest.mark.realtime
@pytest.mark.parametrize("page", RUN_PAGES, ids=_ids)
def test_examples_run_as_written(page: Path, page_runs: dict[Path, Future[tuple[int, list[str]]]]) -> None:
    count, failures = page_runs[page].result(timeout=BLOCK_TIMEOUT * 20)
    assert not failures, f"{len(failures)} of {count} blocks failed\n\n" + "\n\n".join(failures)


def test_the_harness_reads_markers_and_rewrites_ports(tmp_path: Path) -> None:
    """The parser and the port rewriting themselves, on a page made up here."""
    page = tmp_path / "page.md"
    page.write_text(textwrap.dedent("""\
        text
        <!-- not-run: talks to a real gripper -->
        ```python
        Gripper("tcp://192.168.1.20")
        ```

        ```sh
        wsg --url "udp://127.0.0.1:1500" state
        ```
        ```
        untagged
        ```
        """), encoding="utf-8")
    got = blocks_of(page)
    assert [(b.line, b.lang, b.not_run) for b in got] == [(3, "python", "talks to a real gripper"), (7, "sh", None),
                                                          (10, "", None)]
    sim = PageSim.__new__(PageSim)
    sim.reply_port = 40001
    sim.proxy_port = 42000
    sim.urls = {"tcp": "tcp://127.0.0.1:41000", "udp": "udp://127.0.0.1:41500?reply_port=40001",
                "modbus": "modbus-tcp://127.0.0.1:45020", "web": "http://127.0.0.1:48080/"}
    assert sim.rewrite(got[1].code) == 'wsg --url "udp://127.0.0.1:41500?reply_port=40001" state\n'
    assert sim.rewrite("tcp://127.0.0.1:1000 udp://127.0.0.1:1500?reply_port=0 -p 5020 :8080/") == \
        "tcp://127.0.0.1:41000 udp://127.0.0.1:41500?reply_port=0 -p 45020 :48080/"
    assert sim.rewrite("wsg proxy --listen 2000; wsg --url tcp://127.0.0.1:2000 home; sleep 2000") == \
        "wsg proxy --listen 42000; wsg --url tcp://127.0.0.1:42000 home; sleep 2000"
