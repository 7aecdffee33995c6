#!/usr/bin/env bash
# Runs the whole test suite on a fresh machine: installs what it needs (a venv with the package and
# its test extras; Debian's chromium, mbpoll, tshark and npm for the browser, Modbus-master and capture
# tests; axe-core from npm for the accessibility check), then lint, types, and pytest. Extra arguments go to pytest.
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PYTHON:-python3}
if [ ! -x .venv/bin/python ]; then
    "$PY" -m venv .venv
fi
.venv/bin/python -m pip install -q --disable-pip-version-check -e ".[test]"
need=()
command -v chromium >/dev/null 2>&1 || need+=(chromium)
command -v mbpoll >/dev/null 2>&1 || need+=(mbpoll)
command -v tshark >/dev/null 2>&1 || need+=(tshark)
command -v npm >/dev/null 2>&1 || need+=(npm)
if [ ${#need[@]} -gt 0 ]; then
    SUDO=""
    [ "$(id -u)" -eq 0 ] || SUDO="sudo"
    echo "installing Debian packages: ${need[*]}"
    $SUDO apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq "${need[@]}" >/dev/null
fi
# axe-core (npm) checks the web pages for WCAG violations in the browser tests
if [ ! -f .venv/axe/node_modules/axe-core/axe.min.js ]; then
    npm install --prefix .venv/axe --no-save --no-audit --no-fund --loglevel=error axe-core@4 >/dev/null
fi
echo "== ruff"
.venv/bin/ruff check src tests benchmarks
echo "== mypy (strict)"
.venv/bin/mypy
echo "== import contracts (.importlinter)"
.venv/bin/lint-imports --no-cache
echo "== pytest"
.venv/bin/python -m pytest -q "$@"
if [ $# -eq 0 ]; then
    # The pymodbus pin's lower end (pyproject.toml) is supported too: run the fieldbus tests on it, shadowing the
    # installed (newest) pymodbus with the oldest allowed one.
    oldest=$(.venv/bin/python -c 'import re,tomllib;d=tomllib.load(open("pyproject.toml","rb"));print(next(re.search(r">=([0-9.]+)",x).group(1) for x in d["project"]["dependencies"] if x.startswith("pymodbus")))')
    echo "== fieldbus tests on the oldest supported pymodbus ($oldest)"
    target=.venv/pymodbus-$oldest
    [ -d "$target/pymodbus" ] || .venv/bin/python -m pip install -q --disable-pip-version-check --no-deps --target "$target" "pymodbus==$oldest"
    PYTHONPATH="$target" .venv/bin/python -m pytest -q -p no:cacheprovider tests/fieldbus tests/server/test_connection_caps.py
fi
