#!/usr/bin/env bash
# `cmake --install` the build tree into a scratch prefix, then configure, build and run a project
# that only knows find_package(voxtier). Usage: install_consumer.sh BUILD_DIR SOURCE_DIR
# [CXX_FLAGS LINKER_FLAGS]: a sanitizer build's static libraries need the consumer to compile and
# link with the same sanitizer flags.
set -euo pipefail
build="$1"
src="$2"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
cmake --install "$build" --prefix "$work/prefix" >/dev/null
cmake -S "$src/tests/consumer" -B "$work/consumer" -G Ninja -DCMAKE_PREFIX_PATH="$work/prefix" \
    -DCMAKE_CXX_FLAGS="${3:-}" -DCMAKE_EXE_LINKER_FLAGS="${4:-}" >/dev/null
cmake --build "$work/consumer" >/dev/null
"$work/consumer/consumer"
