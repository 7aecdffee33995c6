#!/usr/bin/env bash
# Runs the test suite on another supported Python (scripts/test.sh starts it for the oldest and the newest,
# beside the main run). Usage: scripts/other-python.sh 3.10 [pytest arguments...]
#
# Finding the interpreter, first hit wins:
#   1. $PYWSG_PYTHON_3_10 (the version's dots as underscores): a path to the interpreter;
#   2. python3.10 on PATH;
#   3. pyenv's newest installed 3.10.x (`pyenv versions --bare`, or $PYENV_ROOT/versions/3.10.* without pyenv on
#      PATH), e.g. /root/.pyenv/versions/3.10.13.
# Each candidate must run and report 3.10: a pyenv shim named python3.10 exists even where 3.10 is not selected.
# Where none is found it says so on stdout and exits 3: scripts/test.sh reports that version as NOT TESTED
# (and fails when PYWSG_REQUIRE_PYTHONS=1), so a missing interpreter never passes silently.
# The venv is .venv-py3.10 in the checkout, made once and reused; the test extra installs there with the pins
# pyproject.toml gives that version.
set -euo pipefail
cd "$(dirname "$0")/.."
ver=${1:?usage: scripts/other-python.sh X.Y [pytest args...]}
shift
var="PYWSG_PYTHON_${ver//./_}"
works() {  # the interpreter runs and is version $ver (a pyenv shim for a version not selected does not run)
    [ -n "$1" ] && [ "$("$1" -c 'import sys; print("%d.%d" % sys.version_info[:2])' 2>/dev/null)" = "$ver" ]
}
candidates=()
[ -n "${!var:-}" ] && candidates+=("${!var}")
command -v "python$ver" >/dev/null 2>&1 && candidates+=("$(command -v "python$ver")")
root=${PYENV_ROOT:-$HOME/.pyenv}
if command -v pyenv >/dev/null 2>&1; then
    found=$(pyenv versions --bare 2>/dev/null | grep -E "^${ver//./\\.}\.[0-9]+$" | sort -t. -k3,3n | tail -n 1 || true)
    [ -n "$found" ] && candidates+=("$(pyenv prefix "$found" 2>/dev/null)/bin/python")
fi
for d in $(ls -d "$root/versions/$ver".* 2>/dev/null | sort -t. -k3,3n -r); do
    candidates+=("$d/bin/python")
done
py=""
for c in "${candidates[@]}"; do
    if works "$c"; then py=$c; break; fi
done
if [ -z "$py" ]; then
    [ -n "${!var:-}" ] && echo "$var=${!var} is not a Python $ver interpreter"
    echo "no Python $ver interpreter found (set $var, put python$ver on PATH, or install it with pyenv)"
    exit 3
fi
venv=.venv-py$ver
if [ ! -x "$venv/bin/python" ]; then
    echo "making $venv from $py ($("$py" -V 2>&1))"
    "$py" -m venv "$venv"
fi
echo "installing pywsg[test] into $venv"
"$venv/bin/python" -m pip install -q --disable-pip-version-check -e ".[test]"
echo "== pytest on $("$venv/bin/python" -V 2>&1) ($venv)"
exec "$venv/bin/python" -m pytest -q -p no:cacheprovider "$@"
