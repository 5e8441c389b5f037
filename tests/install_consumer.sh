#!/usr/bin/env bash
# `cmake --install` the build tree into a scratch prefix, then, knowing only the prefix:
#  - the installed headers are <voxtier/module/...> alone, including each other that way;
#  - tests/consumer (find_package(voxtier)) configures, builds and runs;
#  - the installed example sources (share/doc/voxtier/examples) build, and render_scene writes
#    the installed CLI's images of the installed scenes byte for byte (tests/example_test.sh).
# Usage: install_consumer.sh BUILD_DIR SOURCE_DIR [CXX_FLAGS LINKER_FLAGS]: a sanitizer build's
# static libraries need the consumer to compile and link with the same sanitizer flags.
set -euo pipefail
build="$1"
src="$2"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
prefix="$work/prefix"
cmake --install "$build" --prefix "$prefix" >/dev/null

# Only voxtier/ under include/, and no header reaching a module by its bare folder name.
if [ "$(ls "$prefix/include")" != "voxtier" ]; then
    echo "install_consumer: include/ holds $(ls "$prefix/include" | tr '\n' ' ')" >&2
    exit 1
fi
if grep -rnE '#include "(core|device|volumetric|impostor_cache|lod|compose|image_files)/' \
    "$prefix/include"; then
    echo "install_consumer: installed headers include modules without voxtier/" >&2
    exit 1
fi

configure() { # SOURCE BINARY
    cmake -S "$1" -B "$2" -G Ninja -DCMAKE_PREFIX_PATH="$prefix" \
        -DCMAKE_CXX_FLAGS="${CXX_FLAGS:-}" -DCMAKE_EXE_LINKER_FLAGS="${LINKER_FLAGS:-}" >/dev/null
    cmake --build "$2" >/dev/null
}
CXX_FLAGS="${3:-}" LINKER_FLAGS="${4:-}" configure "$src/tests/consumer" "$work/consumer"
"$work/consumer/consumer"

CXX_FLAGS="${3:-}" LINKER_FLAGS="${4:-}" configure "$prefix/share/doc/voxtier/examples" \
    "$work/examples"
bash "$src/tests/example_test.sh" "$prefix/bin/voxtier" "$work/examples/render_scene" \
    "$prefix/share/voxtier/scenes"

# OpenImageIO's module (image_files/detail/image_library_module.hpp) is the installed one for both
# the installed CLI (found beside it) and the example built against the prefix (its run path),
# not the build tree's, which the loader would also find.
module="$(find "$prefix" -name libvoxtier_openimageio.so)"
[[ -n "$module" ]] || { echo "install_consumer: no libvoxtier_openimageio.so installed" >&2; exit 1; }
opened() { # LOG...: the module's paths, as the loader names it where it loads OpenImageIO for it
    grep -ho 'needed by [^ ]*libvoxtier_openimageio\.so' "$@" | sed 's/^needed by //' | sort -u
}
LD_DEBUG=files LD_DEBUG_OUTPUT="$work/cli" "$prefix/bin/voxtier" render \
    "$prefix/share/voxtier/scenes/default.json" -o "$work/m_cli.png" >/dev/null
LD_DEBUG=files LD_DEBUG_OUTPUT="$work/example" "$work/examples/render_scene" \
    "$prefix/share/voxtier/scenes/default.json" "$work/m_example.png"
for who in cli example; do
    got="$(opened "$work/$who".*)"
    if [[ "$got" != "$module" ]]; then
        echo "install_consumer: the $who loaded '${got//$'\n'/, }', not the installed $module" >&2
        exit 1
    fi
done
cmp "$work/m_cli.png" "$work/m_example.png"
# A module that cannot be loaded: one line naming the output file and the loader's reason, exit
# status 2, before anything is rendered, and no file written.
echo "not a library" >"$module"
rc=0
msg="$("$prefix/bin/voxtier" render "$prefix/share/voxtier/scenes/default.json" \
    -o "$work/broken.png" 2>&1)" || rc=$?
if [[ $rc -ne 2 || $(printf '%s\n' "$msg" | wc -l) -ne 1 || "$msg" != *"$module"* ||
    -e "$work/broken.png" ]]; then
    echo "install_consumer: a broken module gave exit status $rc and: $msg" >&2
    exit 1
fi
echo "install_consumer: the installed module loaded by the CLI and the example; a broken one: $msg"
