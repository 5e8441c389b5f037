#!/usr/bin/env bash
# Makes one folder that runs voxtier on a machine with a Vulkan loader and driver but none of
# this project's libraries and no network (a GPU machine; README "On a GPU machine"):
#   voxtier         the CLI, built without OpenImageIO (writes .pam; VOXTIER_IMAGE_FILES=OFF),
#                   DT_RPATH $ORIGIN/lib, debug info stripped
#   lib/            the shared libraries it links that the other machine may lack (ldd), less the
#                   C library and loader family and libvulkan.so.1, which that machine brings;
#                   lib/fallback/ the C++ runtime, used only where that machine has none
#   scenes/         the golden and bench scenes and the bundled models they name (scenes/vox)
#   gpu_check.sh    tools/gpu_check.sh: identity checks and the bench, report.md + results.csv
#   MANIFEST.txt    what is in it, from which commit, and its size
# The shaders are SPIR-V embedded in the binary at build time (volumetric/CMakeLists.txt) and the
# bench's report template likewise (apps/CMakeLists.txt): no data files besides the scenes.
#
# Usage: tools/portable.sh [--from BUILD_DIR] [OUTDIR]     (OUTDIR default: voxtier-portable)
#   default      configures build-portable (VOXTIER_IMAGE_FILES=OFF, no tests, RelWithDebInfo,
#                no -march=native: Highway and Embree pick their SIMD code at run time) and
#                builds the CLI there: a second build of the renderer.
#   --from DIR   packs DIR/voxtier-portable, which an ordinary build tree links from its own
#                objects (VOXTIER_PORTABLE_CLI, on with the tests): no second build. The test
#                tests/portable_test.sh uses this.
# Fails when the folder would reach 64 MiB (the limit of what travels to the GPU machine).
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"

from=""
out=""
while [[ $# -gt 0 ]]; do
    case "$1" in
    --from)
        from="${2:?--from needs a build directory}"
        shift 2
        ;;
    -h | --help)
        sed -n '2,23p' "$0"
        exit 0
        ;;
    -*)
        echo "portable.sh: unknown option '$1' (see --help)" >&2
        exit 2
        ;;
    *)
        out="$1"
        shift
        ;;
    esac
done
out="${out:-voxtier-portable}"
mkdir -p "$out"
out="$(cd "$out" && pwd)"
limit_mib=64

if [[ -n "$from" ]]; then
    bin="$from/voxtier-portable"
    [[ -x "$bin" ]] || {
        echo "portable.sh: $bin not found (build the tree with VOXTIER_PORTABLE_CLI=ON, the default with tests)" >&2
        exit 1
    }
else
    bash "$root/tools/setup.sh"
    build="$root/build-portable"
    if [[ ! -f "$build/CMakeCache.txt" ]]; then
        cmake -S "$root" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
            -DVOXTIER_IMAGE_FILES=OFF -DVOXTIER_BUILD_TESTS=OFF >/dev/null
    fi
    cmake --build "$build" -j "$(nproc)" --target voxtier_cli
    bin="$build/voxtier"
fi

# What makes the folder portable, checked on the binary itself.
if ldd "$bin" | grep -i openimageio >/dev/null; then
    echo "portable.sh: $bin links OpenImageIO; it must not (VOXTIER_IMAGE_FILES=OFF)" >&2
    exit 1
fi
if ! readelf -d "$bin" | grep 'RPATH.*\[\$ORIGIN/lib\]$' >/dev/null; then
    echo "portable.sh: $bin has not exactly the DT_RPATH \$ORIGIN/lib" >&2
    exit 1
fi
if ldd "$bin" | grep 'not found' >/dev/null; then
    ldd "$bin" | grep 'not found' >&2
    exit 1
fi

# A folder of ours only: never empty a folder that holds anything else.
if [[ -n "$(ls -A "$out")" && ! -f "$out/MANIFEST.txt" ]]; then
    echo "portable.sh: $out is not empty and not a portable folder; choose another" >&2
    exit 1
fi
rm -rf "${out:?}/voxtier" "${out:?}/lib" "${out:?}/scenes" "${out:?}/gpu_check.sh" "${out:?}/MANIFEST.txt"
mkdir -p "$out/lib"

strip --strip-debug -o "$out/voxtier" "$bin"
# The C library and the dynamic loader come with every Linux (and must match its kernel and
# loader); the Vulkan loader comes with the GPU's driver. Everything else is copied.
system='^(linux-vdso\.so|linux-gate\.so|ld-linux[-a-z0-9_.]*\.so|libc\.so|libm\.so|libdl\.so|libpthread\.so|librt\.so|libresolv\.so|libutil\.so|libmvec\.so|libvulkan\.so)'
# The C++ runtime goes to lib/fallback/, off the search path: a machine with a Vulkan driver
# has one (Mesa's drivers link it), as new as its driver needs, and a copy of ours found first
# would be older than a newer distribution's driver asks for. gpu_check.sh adds lib/fallback to
# LD_LIBRARY_PATH only where the machine has none. MANIFEST.txt says which versions it needs.
fallback='^(libstdc\+\+\.so|libgcc_s\.so)'
mkdir -p "$out/lib/fallback"
libs=()
while read -r name path; do
    [[ "$name" =~ $system ]] && continue
    [[ -f "$path" ]] || continue
    if [[ "$name" =~ $fallback ]]; then
        libs+=("fallback/$name")
        strip --strip-unneeded -o "$out/lib/fallback/$name" "$path"
    else
        libs+=("$name")
        strip --strip-unneeded -o "$out/lib/$name" "$path"
    fi
done < <(ldd "$bin" | awk '$2 == "=>" && $3 ~ /^\// {print $1, $3}')

cp -r "$root/scenes" "$out/scenes"
install -m 755 "$root/tools/gpu_check.sh" "$out/gpu_check.sh"

needs() { # PREFIX FILES...: the newest symbol version PREFIX_x.y the files ask for
    local prefix="$1"
    shift
    objdump -T "$@" | grep -o "${prefix}_[0-9.]*" | sort -uV | tail -1 | sed "s/${prefix}_//"
}
bytes=$(du -sb "$out" | cut -f1)
mib=$(awk -v b="$bytes" 'BEGIN {printf "%.1f", b / 1048576}')
{
    echo "voxtier portable folder (tools/portable.sh)"
    echo "commit: $(git -C "$root" rev-parse --short HEAD 2>/dev/null || echo unknown)$(git -C "$root" diff --quiet 2>/dev/null || echo ' (with local changes)')"
    echo "built on: $(. /etc/os-release && echo "$PRETTY_NAME"), glibc $(ldd --version | head -1 | awk '{print $NF}')"
    echo "needs: glibc $(needs GLIBC "$out/voxtier" "$out"/lib/*.so*) or newer; a libstdc++ with GLIBCXX_$(needs GLIBCXX "$out/voxtier" "$out"/lib/*.so*) (else lib/fallback/)"
    echo "size: $mib MiB"
    echo "run: ./gpu_check.sh [OUTDIR]   or   ./voxtier render scenes/default.json -o out.pam"
    echo "lib/ (${#libs[@]} libraries):"
    (cd "$out/lib" && find . -type f -printf '%s %P\n' | sort -rn |
        awk '{printf "  %-40s %6.2f MiB\n", $2, $1 / 1048576}')
} >"$out/MANIFEST.txt"

echo "portable: $out: $mib MiB (binary $(du -b "$out/voxtier" | awk '{printf "%.1f", $1 / 1048576}') MiB, ${#libs[@]} libraries $(du -sb "$out/lib" | awk '{printf "%.1f", $1 / 1048576}') MiB, scenes $(du -sb "$out/scenes" | awk '{printf "%.1f", $1 / 1048576}') MiB)"
if ((bytes >= limit_mib * 1048576)); then
    echo "portable.sh: the folder is $mib MiB, over the $limit_mib MiB limit" >&2
    exit 1
fi
