#!/usr/bin/env bash
# Build docker-compose.yml's image from scratch without a registry, bring it up, fly a
# mission through it over REST, bring it down (tests/docker/test_compose.py), printing the
# time of each step. `make compose-check` runs it; docs/docker.md explains it.
#
#   scripts/compose-check.sh             all of it: engine, wheelhouse, base, build, test
#   scripts/compose-check.sh engine      a Docker engine: Debian's docker.io installed and
#                                        started where none answers (root and apt-get only)
#   scripts/compose-check.sh wheelhouse  .wheelhouse/ from requirements-lock.txt (hashes checked)
#   scripts/compose-check.sh base        the base image $BASE_IMAGE from debootstrap
#   scripts/compose-check.sh build       the image, from $GCS_PPF_BASE
#
# Environment: GCS_PPF_BASE (the base image; default: the debootstrap one, gcs-ppf-base:bookworm;
# python:3.11-slim where a registry is reachable), FRESH=1 (remove the images first and
# build without the cache: the time from an empty image store).
# Where no engine can be had, it says so and exits 0 having checked nothing.
set -euo pipefail
cd "$(dirname "$0")/.."

BASE_IMAGE=gcs-ppf-base:bookworm
SUITE=bookworm
export GCS_PPF_BASE=${GCS_PPF_BASE:-$BASE_IMAGE}
PY=${PY:-python3}
[ -x .venv/bin/python ] && PY=.venv/bin/python

say() { printf 'compose-check: %s\n' "$*"; }
timed() {  # timed WHAT COMMAND...: run it, print how long it took
    local what=$1 start end
    shift
    start=$(date +%s)
    "$@"
    end=$(date +%s)
    say "$what: $((end - start)) s"
}

compose() {
    if docker compose version >/dev/null 2>&1; then
        docker compose "$@"
    else
        docker-compose "$@"
    fi
}

engine() {
    if docker info >/dev/null 2>&1; then
        return 0
    fi
    if [ "$(id -u)" != 0 ] || ! command -v apt-get >/dev/null; then
        say "no Docker engine answers and this is not root with apt-get: skipped"
        return 1
    fi
    if ! command -v dockerd >/dev/null || ! command -v debootstrap >/dev/null \
        || ! { docker compose version || command -v docker-compose; } >/dev/null 2>&1; then
        apt-get update -qq
        DEBIAN_FRONTEND=noninteractive apt-get install -y -qq \
            docker.io docker-compose debootstrap >/dev/null
    fi
    mkdir -p out
    say "starting dockerd (log: out/dockerd.log)"
    setsid nohup dockerd >out/dockerd.log 2>&1 </dev/null &
    for _ in $(seq 60); do
        docker info >/dev/null 2>&1 && return 0
        sleep 1
    done
    say "dockerd did not start (out/dockerd.log): skipped"
    return 1
}

wheelhouse() {
    # pip download checks every file against the lock's hashes; files already there are kept.
    "$PY" -m pip download --quiet --disable-pip-version-check --require-hashes \
        -r requirements-lock.txt -d .wheelhouse
}

base() {
    if [ "${FRESH:-}" != 1 ] && docker image inspect "$BASE_IMAGE" >/dev/null 2>&1; then
        say "base image $BASE_IMAGE already there"
        return 0
    fi
    local root
    root=$(mktemp -d)
    # Debian's own mirror, as the host's apt reaches it: the default of debootstrap.
    debootstrap --variant=minbase --include=python3,python3-venv "$SUITE" "$root" >/dev/null
    rm -rf "$root"/var/cache/apt/archives/*.deb "$root"/var/lib/apt/lists/*
    tar -C "$root" -c . | docker import - "$BASE_IMAGE" >/dev/null
    rm -rf "$root"
}

build() {
    # Both services run the one image, gcs-ppf:local: building it for one builds it for both.
    if [ "${FRESH:-}" = 1 ]; then
        compose build --no-cache sitl
    else
        compose build sitl
    fi
}

check() {
    GCS_PPF_DOCKER=1 "$PY" -m pytest -m docker tests/docker -s -p no:cacheprovider
}

case "${1:-all}" in
    engine) engine || exit 0 ;;
    wheelhouse) timed "wheelhouse" wheelhouse ;;
    base) timed "base image" base ;;
    build) timed "image build" build ;;
    test) check ;;
    all)
        start=$(date +%s)
        engine || exit 0
        if [ "${FRESH:-}" = 1 ]; then
            compose down --rmi all --volumes >/dev/null 2>&1 || true
            docker image rm "$BASE_IMAGE" >/dev/null 2>&1 || true
            docker image prune --force >/dev/null
        fi
        timed "wheelhouse" wheelhouse
        [ "$GCS_PPF_BASE" = "$BASE_IMAGE" ] && timed "base image (debootstrap)" base
        timed "image build" build
        check
        say "total: $(($(date +%s) - start)) s"
        ;;
    *) echo "usage: $0 [engine|wheelhouse|base|build|test|all]" >&2; exit 2 ;;
esac
