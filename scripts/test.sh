#!/usr/bin/env bash
# Runs the whole test suite on a fresh machine: installs what it needs (a venv with the package and
# its test extras; Debian's chromium, mbpoll, tshark and npm for the browser, Modbus-master and capture
# tests; socat for serial lines with a real port's code path; axe-core from npm for the accessibility check), then lint, types (also for Python 3.10), the
# package build (python -m build + twine check, in tests/test_packaging.py) and pytest in parallel
# (pytest-xdist). Extra arguments go to pytest; without any, the fieldbus tests also run on the oldest
# supported pymodbus (beside the main run), and then the suite (all but the browser and container tests) on the
# oldest and the newest supported Python (scripts/other-python.sh; the versions are the lowest and highest
# "Programming Language :: Python :: 3.X" classifiers of pyproject.toml).
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PYTHON:-python3}
if [ ! -x .venv/bin/python ]; then
    "$PY" -m venv .venv
fi
echo "== installing pywsg[test] into .venv (first run: a minute or so)"
.venv/bin/python -m pip install -q --disable-pip-version-check -e ".[test]"
# The virtual gripper's container image for the tests marked `container` (tests/container), built beside lint
# and the other tests; installs podman, runc and mmdebstrap when missing (docs/container.md, "The tests").
echo "== the container image for the container tests (scripts/container-env.sh; log: .venv/container-env.log), in the background"
bash scripts/container-env.sh start >.venv/container-env.log 2>&1 &
container_pid=$!
old_pid=""
py_pids=()
trap 'for p in "$old_pid" "$container_pid" "${py_pids[@]}"; do [ -n "$p" ] && kill "$p" 2>/dev/null; done' EXIT
need=()
command -v chromium >/dev/null 2>&1 || need+=(chromium)
command -v mbpoll >/dev/null 2>&1 || need+=(mbpoll)
command -v tshark >/dev/null 2>&1 || need+=(tshark)
command -v npm >/dev/null 2>&1 || need+=(npm)
command -v socat >/dev/null 2>&1 || need+=(socat)
if [ ${#need[@]} -gt 0 ]; then
    SUDO=""
    [ "$(id -u)" -eq 0 ] || SUDO="sudo"
    echo "installing Debian packages: ${need[*]}"
    # another apt-get or dpkg (unattended upgrades, a second job) holds the lock: wait for it, up to 10 minutes
    APT=(apt-get -o DPkg::Lock::Timeout=600)
    $SUDO "${APT[@]}" update -qq
    DEBIAN_FRONTEND=noninteractive $SUDO "${APT[@]}" install -y -qq "${need[@]}" >/dev/null
fi
# axe-core (npm) checks the web pages for WCAG violations in the browser tests
if [ ! -f .venv/axe/node_modules/axe-core/axe.min.js ]; then
    echo "== installing axe-core 4 from npm into .venv/axe (the browser tests' accessibility check)"
    npm install --prefix .venv/axe --no-save --no-audit --no-fund --loglevel=error axe-core@4 >/dev/null
fi
# The ROS 2 test environment (.venv-ros: pinned ROS 2 wheels, two interface packages built with cmake) is built
# once and reused; on a fresh clone it builds beside the lint and type checks below (about 2 minutes of CPU).
echo "== the ROS 2 test environment (scripts/ros-env.sh; log: .venv/ros-env.log), beside the checks"
bash scripts/ros-env.sh >.venv/ros-env.log 2>&1 &
ros_pid=$!
echo "== ruff (target: Python 3.10)"
.venv/bin/ruff check src tests benchmarks
echo "== mypy (strict, Python 3.10)"
.venv/bin/mypy
echo "== import contracts (.importlinter)"
.venv/bin/lint-imports --no-cache
if ! wait "$ros_pid"; then
    tail -n 30 .venv/ros-env.log
    echo "scripts/ros-env.sh failed: the ROS 2 tests cannot run (log above)" >&2
    exit 1
fi
# Hypothesis: the same examples every run, no example database (tests/conftest.py)
export HYPOTHESIS_PROFILE=${HYPOTHESIS_PROFILE:-ci}
# Workers: tests mostly wait (sockets, subprocesses, a browser), so one more than the cores keeps 2 cores busy.
# --dist loadfile: the tests of a module run on one worker, in order, sharing its module-scoped fixtures.
WORKERS=${PYTEST_WORKERS:-$(( $(nproc) + 1 ))}
XDIST=(-n "$WORKERS" --dist loadfile)
py_vers=()
if [ $# -eq 0 ]; then
    # The pymodbus pin's lower end (pyproject.toml) is supported too: the tests marked `pymodbus` run once more on
    # it (the installed, newest pymodbus shadowed by the oldest allowed one), beside the main run: both mostly
    # wait on sockets, so together they take little longer than the main run alone.
    oldest=$(sed -n 's/^ *"pymodbus>=\([0-9.]*\).*/\1/p' pyproject.toml | head -n 1)
    [ -n "$oldest" ] || { echo "no pymodbus>= pin found in pyproject.toml" >&2; exit 1; }
    target=.venv/pymodbus-$oldest
    [ -d "$target/pymodbus" ] || echo "== installing pymodbus $oldest into $target (the oldest supported, for a second run)"
    [ -d "$target/pymodbus" ] || .venv/bin/python -m pip install -q --disable-pip-version-check --no-deps --target "$target" "pymodbus==$oldest"
    PYTHONPATH="$target" .venv/bin/python -m pytest -q -p no:cacheprovider -n 2 --dist load -m pymodbus \
        >.venv/pytest-oldest-pymodbus.log 2>&1 &
    old_pid=$!
fi
echo "== pytest ($WORKERS workers)"
status=0
.venv/bin/python -m pytest -q "${XDIST[@]}" --durations=20 "$@" || status=$?
if [ $# -eq 0 ]; then
    # Then the oldest and the newest supported Python run the suite but its browser and container tests (those
    # drive pages and the image's own Python; they run once, on the default Python), the two side by side. After
    # the main run, not beside it: the PROFINET wire tests' controller misses its cycle when five test
    # sessions share the 2 cores.
    mapfile -t pys < <(sed -n 's/^ *"Programming Language :: Python :: \(3\.[0-9]*\)".*/\1/p' pyproject.toml | sort -t. -k2,2n)
    [ ${#pys[@]} -ge 2 ] || { echo "no Python version classifiers in pyproject.toml" >&2; exit 1; }
    for v in "${pys[0]}" "${pys[-1]}"; do
        [ "$v" = "$(.venv/bin/python -c 'import sys; print("%d.%d" % sys.version_info[:2])')" ] && continue
        echo "== the suite on Python $v starts (scripts/other-python.sh; log: .venv/pytest-py$v.log)"
        bash scripts/other-python.sh "$v" -n 2 --dist loadfile -m "not browser and not container" >".venv/pytest-py$v.log" 2>&1 &
        py_pids+=("$!")
        py_vers+=("$v")
    done
fi
if [ -n "$old_pid" ]; then
    old_status=0
    wait "$old_pid" || old_status=$?
    old_pid=""
    echo "== the tests that use pymodbus, on the oldest supported pymodbus ($oldest; run beside the main run)"
    tail -n 25 .venv/pytest-oldest-pymodbus.log
    [ "$old_status" -eq 0 ] || status=$old_status
fi
for i in "${!py_pids[@]}"; do
    v=${py_vers[$i]}
    py_status=0
    wait "${py_pids[$i]}" || py_status=$?
    echo "== the suite but its browser and container tests, on Python $v (scripts/other-python.sh)"
    if [ "$py_status" -eq 3 ]; then
        # no interpreter: say so loudly; fail only where every version is required
        cat ".venv/pytest-py$v.log"
        echo "WARNING: Python $v NOT TESTED: no interpreter found (see docs/testing.md)"
        [ "${PYWSG_REQUIRE_PYTHONS:-0}" = 1 ] && status=1
        continue
    fi
    grep -E '^(FAILED|ERROR) ' ".venv/pytest-py$v.log" || true
    tail -n 3 ".venv/pytest-py$v.log"
    [ "$py_status" -eq 0 ] || status=$py_status
done
py_pids=()
wait "$container_pid" 2>/dev/null || true   # the container tests waited for it; a failed build failed them
container_pid=""
bash scripts/container-env.sh clean          # the test image goes; the Debian base pywsg-base:bookworm stays
exit "$status"
