#!/usr/bin/env bash
# Builds the virtual gripper's container image from the Containerfile at the root (docs/container.md).
#
#   scripts/build-image.sh [TAG]          default tag: pywsg-sim:<version>
#
# With podman or docker, whichever works here (ENGINE=podman|docker chooses). The wheels (pywsg[web] and
# its dependencies) are built on the host with `pip wheel` into build/image/wheels, so the image build
# itself runs without network. The base (WSG_IMAGE_BASE, default python:3.11-slim-bookworm) is pulled;
# where it cannot be (no registry reachable), a Debian 12 base with Python is made with mmdebstrap and
# kept as pywsg-base:bookworm for the next build (WSG_IMAGE_BASE=pywsg-base:bookworm uses it at once).
# Prints the tag built on its last line.
#
# Environment: ENGINE, WSG_IMAGE_BASE, WSG_IMAGE_SOURCE (the OCI source label), PYTHON (the Python that
# builds the wheels: it must be the base's Python version), PODMAN_ARGS (global podman options; default:
# `--runtime runc --cgroup-manager=cgroupfs` when runc is installed, see docs/container.md).
set -euo pipefail
cd "$(dirname "$0")/.."

VERSION=$(sed -n 's/^version = "\(.*\)"/\1/p' pyproject.toml | head -n 1)
TAG=${1:-pywsg-sim:$VERSION}
DEFAULT_BASE=docker.io/library/python:3.11-slim-bookworm
LOCAL_BASE=pywsg-base:bookworm
BASE=${WSG_IMAGE_BASE:-$DEFAULT_BASE}
CTX=build/image
ULIMITS=(--ulimit nofile=4096:4096 --ulimit nproc=4096:4096)

# -- the engine ----------------------------------------------------------------------------------------
if [ -z "${ENGINE:-}" ]; then
    if command -v podman >/dev/null 2>&1; then
        ENGINE=podman
    elif command -v docker >/dev/null 2>&1 && docker info >/dev/null 2>&1; then
        ENGINE=docker   # a docker client without a reachable daemon is no engine
    else
        echo "build-image.sh: neither podman nor a running docker found (apt-get install podman runc)" >&2
        exit 1
    fi
fi
if [ "$ENGINE" = podman ]; then
    if [ -z "${PODMAN_ARGS+set}" ]; then
        PODMAN_ARGS=""
        command -v runc >/dev/null 2>&1 && PODMAN_ARGS="--runtime runc --cgroup-manager=cgroupfs"
    fi
    # shellcheck disable=SC2206
    ENG=(podman $PODMAN_ARGS)
    # the OCI format has no HEALTHCHECK; --layers=false: no intermediate images left behind
    BUILD_ARGS=(--format docker --pull=never --layers=false)
else
    ENG=(docker)
    BUILD_ARGS=()
fi

has_image() { "${ENG[@]}" image inspect "$1" >/dev/null 2>&1; }

# -- the base --------------------------------------------------------------------------------------------
make_base() {
    command -v mmdebstrap >/dev/null 2>&1 || { echo "build-image.sh: $BASE cannot be pulled and mmdebstrap " \
        "is not installed (apt-get install mmdebstrap)" >&2; exit 1; }
    echo "== making $LOCAL_BASE with mmdebstrap (Debian 12, python3; no documentation, man pages or locales)" >&2
    local tar
    tar=$(mktemp --suffix=.tar)
    # essential: no apt; the merged-usr hook installs usr-is-merged (else apt picks usrmerge and with it
    # perl, 47 MB); passwd for useradd; no Recommends
    mmdebstrap --quiet --variant=essential --hook-dir=/usr/share/mmdebstrap/hooks/merged-usr \
        --include=python3,python3-venv,passwd \
        --aptopt='APT::Install-Recommends "false"' \
        --dpkgopt='path-exclude=/usr/share/doc/*' --dpkgopt='path-include=/usr/share/doc/*/copyright' \
        --dpkgopt='path-exclude=/usr/share/man/*' --dpkgopt='path-exclude=/usr/share/info/*' \
        --dpkgopt='path-exclude=/usr/share/locale/*' --dpkgopt='path-exclude=/usr/share/lintian/*' \
        bookworm "$tar" >&2
    "${ENG[@]}" import --change 'CMD ["/bin/bash"]' "$tar" "$LOCAL_BASE" >/dev/null
    rm -f "$tar"
}

if ! has_image "$BASE"; then
    if [ "$BASE" = "$LOCAL_BASE" ]; then
        make_base
    elif has_image "$LOCAL_BASE" && [ -z "${WSG_IMAGE_BASE:-}" ]; then
        BASE=$LOCAL_BASE   # made by an earlier run where the default base could not be pulled
    elif timeout 60 "${ENG[@]}" pull --quiet "$BASE" >/dev/null 2>&1; then
        :
    elif [ -z "${WSG_IMAGE_BASE:-}" ]; then
        echo "== $BASE cannot be pulled here: using a Debian base made with mmdebstrap" >&2
        BASE=$LOCAL_BASE
        make_base
    else
        echo "build-image.sh: cannot pull $BASE" >&2
        exit 1
    fi
fi

# -- the wheels ------------------------------------------------------------------------------------------
PY=${PYTHON:-}
if [ -z "$PY" ]; then
    if [ -x .venv/bin/python ]; then PY=.venv/bin/python; else PY=python3; fi
fi
echo "== wheels of pywsg[web] and its dependencies ($("$PY" -c 'import sys; print("Python %d.%d" % sys.version_info[:2])'))" >&2
rm -rf "$CTX"
mkdir -p "$CTX/wheels"
NO_ISOLATION=()   # building pywsg's own wheel with the setuptools at hand saves a build environment
"$PY" -c 'import setuptools, sys; sys.exit(int(setuptools.__version__.split(".")[0]) < 77)' 2>/dev/null \
    && NO_ISOLATION=(--no-build-isolation)
"$PY" -m pip wheel --quiet --disable-pip-version-check "${NO_ISOLATION[@]}" --wheel-dir "$CTX/wheels" '.[web]' >&2

# -- the image -------------------------------------------------------------------------------------------
SOURCE=${WSG_IMAGE_SOURCE:-$(git config --get remote.origin.url 2>/dev/null || true)}
REVISION=$(git rev-parse HEAD 2>/dev/null || true)
echo "== $ENGINE build $TAG from $BASE" >&2
"${ENG[@]}" build "${BUILD_ARGS[@]}" "${ULIMITS[@]}" --network none \
    --build-arg BASE="$BASE" --build-arg VERSION="$VERSION" --build-arg SOURCE="$SOURCE" \
    --build-arg REVISION="$REVISION" --build-arg CREATED="$(date -u +%Y-%m-%dT%H:%M:%SZ)" \
    -f Containerfile -t "$TAG" "$CTX" >&2
echo "$TAG"
