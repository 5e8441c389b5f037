#!/usr/bin/env bash
# OpenImageIO is loaded by the CLI only when a command writes a format that needs it
# (image_files/detail/image_library_module.hpp): `--version`, `--help`, an error and a .pam render
# load none of its libraries; a .png render loads the module and OpenImageIO (what a .png holds is
# tested by render_output_test and the golden tests, which read it back). The dynamic loader's own
# log (LD_DEBUG=files) says what each run loaded.
# Usage: image_module_test.sh VOXTIER SCENES_DIR
set -euo pipefail
cli="$1"
scene="$2/default.json"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
fail() {
    echo "image_module_test: $*" >&2
    exit 1
}
loaded() { # LOG: the files the loader opened, one a line
    grep -o 'file=[^ ]*' "$1" | sed 's/^file=//' | sort -u
}
run() { # NAME ARGS...: runs the CLI with the loader's log in $work/NAME.log
    local name="$1"
    shift
    LD_DEBUG=files LD_DEBUG_OUTPUT="$work/ld_$name" "$cli" "$@" >"$work/$name.out" 2>&1 || true
    cat "$work/ld_$name".* >"$work/$name.log" 2>/dev/null || :
}
run version --version
run help render --help
run error render "$work/missing.json" -o "$work/x.png"
run pam render "$scene" -o "$work/r.pam"
run png render "$scene" -o "$work/r.png"
for name in version help error pam; do
    [[ -s "$work/$name.log" ]] || fail "$name: the loader wrote no log"
    files="$(loaded "$work/$name.log")"
    if [[ "$files" == *OpenImageIO* || "$files" == *voxtier_openimageio* ]]; then
        fail "$name loaded OpenImageIO's libraries: ${files//$'\n'/ }"
    fi
done
# Whole lists, not `| grep -q`: grep's early exit would fail the pipeline (pipefail) by SIGPIPE.
png_files="$(loaded "$work/png.log")"
[[ "$png_files" == *"/libvoxtier_openimageio.so"* ]] || {
    cat "$work/png.out" >&2
    fail "the .png render did not load the module"
}
[[ "$png_files" == *"libOpenImageIO.so"* ]] || fail "the .png render did not load OpenImageIO"
[[ -s "$work/r.pam" && -s "$work/r.png" ]] || fail "a render wrote no image"
echo "image_module_test: OpenImageIO loaded by the .png render alone ($(wc -l <<<"$png_files") files; the .pam render $(loaded "$work/pam.log" | wc -l))"
