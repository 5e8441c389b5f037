#!/usr/bin/env bash
# The README's Quick start in one script.
#   tools/dev.sh render   set up, build, render scenes/default.json to out/default.png
#   tools/dev.sh test     set up, build, run the whole test suite (what .ci/run calls)
#   tools/dev.sh build    set up and build only
# Environment: VOXTIER_BUILD_DIR (default build), VOXTIER_PRESET (a CMake preset, e.g. asan).
set -euo pipefail
cd "$(dirname "$0")/.."

cmd="${1:-render}"
shift || true

bash tools/setup.sh

build_dir="${VOXTIER_BUILD_DIR:-build}"
if [[ -n "${VOXTIER_PRESET:-}" ]]; then
    cmake --preset "$VOXTIER_PRESET" >/dev/null
    build_dir="build-$VOXTIER_PRESET"
elif [[ ! -f "$build_dir/CMakeCache.txt" ]]; then
    cmake -S . -B "$build_dir" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo >/dev/null
fi
case "$cmd" in
build)
    cmake --build "$build_dir" -j "$(nproc)"
    ;;
render)
    cmake --build "$build_dir" -j "$(nproc)" --target voxtier_cli
    mkdir -p out
    "$build_dir/voxtier" render scenes/default.json --out out/default.png "$@"
    ;;
test)
    cmake --build "$build_dir" -j "$(nproc)"
    ctest --test-dir "$build_dir" --output-on-failure -j "$(nproc)" "$@"
    ;;
*)
    echo "usage: tools/dev.sh render|test|build [args...]" >&2
    exit 2
    ;;
esac
