#!/usr/bin/env bash
# The main job on a fresh machine: installs pywsg in a venv, starts the virtual WSG 50 with its web
# interface (http://127.0.0.1:8080), its TCP command interface (port 1000) and Modbus/TCP (port 5020),
# and runs gripping cycles against it with the driver, printing each step. Ctrl-C stops it.
# Arguments go to `wsg demo` (see `wsg demo --help`; e.g. --cycles 3 --exit).
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PYTHON:-python3}
if [ ! -x .venv/bin/python ]; then
    echo "creating a Python virtual environment in .venv"
    "$PY" -m venv .venv
fi
if [ ! -x .venv/bin/wsg ]; then
    echo "installing pywsg and its web interface into .venv (pip install -e '.[web]'; a first run takes about a minute)"
else
    echo "checking pywsg's installation in .venv (pip install -e '.[web]')"
fi
.venv/bin/python -m pip install -q --disable-pip-version-check -e ".[web]"
exec .venv/bin/wsg demo "$@"
