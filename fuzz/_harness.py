"""What the fuzz targets share: run a ``test_one_input(data: bytes)`` under atheris, or under hypothesis.

Every target module defines ``test_one_input(data)`` (the oracle: it raises on a finding) and
``inputs`` (a hypothesis strategy of bytes shaped for that surface, so the fallback explores more than
random bytes would). Run by hand::

    .venv/bin/python fuzz/fuzz_device.py -max_total_time=60          # atheris (coverage-guided)
    .venv/bin/python fuzz/fuzz_device.py --hypothesis --examples 5000  # without atheris
    .venv/bin/python fuzz/fuzz_device.py --suite --examples 300       # what the test suite runs

``pip install atheris`` gives the coverage-guided run; without it (or with ``--hypothesis``) the same
oracle runs on the target's hypothesis strategy (plus random bytes). The test suite runs each target
for a bounded number of examples (tests/server/test_fuzz_targets.py).
"""

from __future__ import annotations

import argparse
import asyncio
import sys
import threading
from collections.abc import Callable
from contextlib import AbstractContextManager, nullcontext
from typing import Any

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

OneInput = Callable[[bytes], None]


def run_hypothesis(test_one_input: OneInput, inputs: st.SearchStrategy[bytes], examples: int,
                   derandomize: bool = False, raw: bool = True) -> None:
    """Run the oracle on ``examples`` inputs: the target's strategy, and (``raw``) plain random bytes."""
    strategy = st.one_of(inputs, st.binary(max_size=2048)) if raw else inputs

    @settings(max_examples=examples, deadline=None, derandomize=derandomize, database=None,
              suppress_health_check=list(HealthCheck))
    @given(strategy)
    def check(data: bytes) -> None:
        test_one_input(data)

    check()


def instrumented(module: str) -> AbstractContextManager[Any]:
    """``atheris.instrument_imports()`` when ``module`` runs as a script under atheris, else nothing
    (imported by the test suite, or run with ``--hypothesis``)."""
    if module != "__main__" or "--hypothesis" in sys.argv or "--suite" in sys.argv:
        return nullcontext()
    try:
        import atheris  # type: ignore[import-untyped,import-not-found,unused-ignore]
    except ImportError:
        return nullcontext()
    return atheris.instrument_imports()  # type: ignore[no-any-return]


def main(test_one_input: OneInput, inputs: st.SearchStrategy[bytes],
         suite_inputs: st.SearchStrategy[bytes] | None = None) -> None:
    """Command line of every target: atheris arguments, or ``--hypothesis [--examples N] [--suite]``.

    ``--suite``: the test suite's inputs (derandomized; for the Modbus target, clear of open finding F1).
    """
    parser = argparse.ArgumentParser(add_help=False)
    parser.add_argument("--hypothesis", action="store_true", help="use the hypothesis fallback")
    parser.add_argument("--examples", type=int, default=2000, help="inputs for the hypothesis fallback")
    parser.add_argument("--suite", action="store_true", help="the test suite's fixed inputs")
    parser.add_argument("-h", "--help", action="store_true")
    args, rest = parser.parse_known_args()
    if args.help:
        print(sys.modules["__main__"].__doc__ or "")
        print("options: --hypothesis [--examples N] | atheris/libFuzzer options (-max_total_time=S, -runs=N)")
        return
    try:
        import atheris
    except ImportError:
        atheris = None
    if atheris is None or args.hypothesis or args.suite:
        if atheris is None and not args.hypothesis:
            print("atheris is not installed: running the hypothesis fallback", file=sys.stderr)
        if args.suite:
            run_hypothesis(test_one_input, suite_inputs or inputs, args.examples, derandomize=True,
                           raw=suite_inputs is None)
        else:
            run_hypothesis(test_one_input, inputs, args.examples)
        print(f"{args.examples} inputs, no finding")
        return
    atheris.Setup([sys.argv[0], *rest], test_one_input)
    atheris.Fuzz()


class LoopThread:
    """An asyncio loop on a daemon thread, for targets that fuzz a real server over loopback sockets."""

    def __init__(self) -> None:
        self.loop = asyncio.new_event_loop()
        self._thread = threading.Thread(target=self.loop.run_forever, daemon=True)
        self._thread.start()

    def run(self, coro: Any, timeout: float = 10) -> Any:
        return asyncio.run_coroutine_threadsafe(coro, self.loop).result(timeout)

    def call(self, fn: Callable[[], Any], timeout: float = 10) -> Any:
        async def _do() -> Any:
            return fn()

        return self.run(_do(), timeout)
