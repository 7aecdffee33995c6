#!/usr/bin/env bash
# The container side of the test suite (tests marked `container`, tests/container/): podman, runc and
# mmdebstrap, and the virtual gripper's image built once per test run.
#
#   scripts/container-env.sh start   install what is missing, build the test image afresh (scripts/test.sh
#                                    runs this in the background at its start, so the build overlaps the
#                                    other tests)
#   scripts/container-env.sh image   print the test image's tag; waits for a running `start`, builds the
#                                    image itself when none is there (what a test calls first)
#   scripts/container-env.sh clean   remove the test image (scripts/test.sh runs this at its end)
#
# One build at a time: a lock file (flock) makes `image` wait for `start`. The base image made with
# mmdebstrap where none can be pulled (pywsg-base:bookworm) is kept between runs: making it costs minutes.
# Output of the build: .venv/container/build.log.
set -euo pipefail
cd "$(dirname "$0")/.."

TAG=${WSG_TEST_IMAGE:-localhost/pywsg-sim:test}
DIR=.venv/container
mkdir -p "$DIR"
LOCK=$DIR/lock
STAMP=$DIR/image   # holds the tag once the image is built; "failed" when the build failed
LOG=$DIR/build.log
PODMAN=(podman --runtime runc --cgroup-manager=cgroupfs)
# What the tests give podman (CONTAINERS_CONF) and `podman kube play` cannot take as options: runc (crun
# refuses hybrid cgroups), cgroupfs, and ulimits below the machine's hard limits (podman's defaults are
# above them on such machines and setrlimit is refused). docs/container.md, "Podman on CI machines".
cat >"$DIR/containers.conf" <<'CONF'
[containers]
default_ulimits = ["nofile=4096:4096", "nproc=4096:4096"]
[engine]
runtime = "runc"
cgroup_manager = "cgroupfs"
CONF

install_tools() {
    local need=()
    command -v podman >/dev/null 2>&1 || need+=(podman)
    command -v runc >/dev/null 2>&1 || need+=(runc)
    command -v mmdebstrap >/dev/null 2>&1 || need+=(mmdebstrap)
    # veth, netns and the bridge for the PROFINET-in-a-container test
    command -v ip >/dev/null 2>&1 || need+=(iproute2)
    if [ ${#need[@]} -gt 0 ]; then
        local sudo=""
        [ "$(id -u)" -eq 0 ] || sudo="sudo"
        echo "installing Debian packages: ${need[*]}"
        # test.sh may be running apt-get beside this: wait for the lock; update the lists only when needed
        local apt=(apt-get -o DPkg::Lock::Timeout=600)
        if ! DEBIAN_FRONTEND=noninteractive $sudo "${apt[@]}" install -y -qq "${need[@]}" >/dev/null; then
            $sudo "${apt[@]}" update -qq
            DEBIAN_FRONTEND=noninteractive $sudo "${apt[@]}" install -y -qq "${need[@]}" >/dev/null
        fi
    fi
}

build() {
    install_tools
    "${PODMAN[@]}" rmi --force "$TAG" >/dev/null 2>&1 || true
    if ENGINE=podman PODMAN_ARGS="--runtime runc --cgroup-manager=cgroupfs" scripts/build-image.sh "$TAG"; then
        echo "$TAG" >"$STAMP"
    else
        echo failed >"$STAMP"
        return 1
    fi
}

case "${1:-}" in
    start)
        exec 9>"$LOCK"
        flock 9
        rm -f "$STAMP"
        build >"$LOG" 2>&1
        ;;
    image)
        exec 9>"$LOCK"
        flock 9
        if [ "$(cat "$STAMP" 2>/dev/null)" = failed ]; then
            echo "container-env.sh: the image build failed; see $LOG" >&2
            tail -n 20 "$LOG" >&2
            exit 1
        fi
        if [ ! -s "$STAMP" ] || ! "${PODMAN[@]}" image exists "$TAG"; then
            build >"$LOG" 2>&1 || { echo "container-env.sh: the image build failed; see $LOG" >&2
                                    tail -n 20 "$LOG" >&2; exit 1; }
        fi
        cat "$STAMP"
        ;;
    clean)
        exec 9>"$LOCK"
        flock 9
        "${PODMAN[@]}" rmi --force "$TAG" >/dev/null 2>&1 || true
        rm -f "$STAMP"
        ;;
    *)
        echo "usage: $0 start|image|clean" >&2
        exit 2
        ;;
esac
