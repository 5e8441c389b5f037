#!/usr/bin/env bash
# The portable folder (tools/portable.sh) runs where none of this project's libraries are: under
# bubblewrap with a root that holds only the folder, the C library and loader family, and the
# Vulkan loader with Mesa's lavapipe and what lavapipe itself links (the part a GPU machine brings
# with its driver). There it renders scenes/default.json byte-identical to the ordinary build
# (colour and the entity ids, as .pam), on the CPU reference and on Vulkan, passes `voxtier
# check` on a golden scene, and refuses a .png with one line; and where even the C++ runtime is
# missing, renders the same with the folder's lib/fallback/. Its ./gpu_check.sh runs as typed. Usage: portable_test.sh BUILD_DIR
# SOURCE_DIR (BUILD_DIR holds voxtier and voxtier-portable).
set -euo pipefail
build="$(cd "$1" && pwd)"
src="$(cd "$2" && pwd)"
command -v bwrap >/dev/null || {
    echo "portable_test: bwrap not found (Debian: bubblewrap; tools/setup.sh installs it)" >&2
    exit 1
}
# A machine where no sandbox can be made (no user namespaces) skips, saying why (CTest: 77).
if ! why=$(bwrap --unshare-all --ro-bind / / true 2>&1); then
    echo "portable_test: skipped: bwrap cannot make a sandbox here: $why"
    exit 77
fi
# grep reads all of ldd's output (no -q): under pipefail an early exit can SIGPIPE ldd and make
# the pipeline fail, which skipped the skip once (the ASan folder is 102 MiB, over the limit).
if ldd "$build/voxtier-portable" | grep -E 'lib(asan|tsan|ubsan)' >/dev/null; then
    echo "portable_test: skipped: a sanitizer build (the sandbox clears the sanitizers' settings)"
    exit 77
fi
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
mkdir -p "$work/out"

bash "$src/tools/portable.sh" --from "$build" "$work/pkg"

# The folder's own command, as its MANIFEST tells a user to type it (git keeps its run bit, and
# portable.sh installs it with one): ./gpu_check.sh from inside the folder, with this machine's
# Vulkan driver.
[[ -x "$work/pkg/gpu_check.sh" ]] || {
    echo "portable_test: the folder's gpu_check.sh is not executable" >&2
    exit 1
}
grep -q '^run: ./gpu_check.sh' "$work/pkg/MANIFEST.txt"
(cd "$work/pkg" && ./gpu_check.sh --short "$work/out/gpu-check") >"$work/out/gpu_check.log" 2>&1 || {
    cat "$work/out/gpu_check.log" >&2
    exit 1
}
grep -q "^gpu_check: Vulkan device used: ." "$work/out/gpu_check.log"
[[ -s "$work/out/gpu-check/report.md" && -s "$work/out/gpu-check/results.csv" ]]
echo "portable_test: ./gpu_check.sh --short from the folder: passed"

# The files a machine with a Vulkan driver has anyway: the loader family, the Vulkan loader, the
# lavapipe ICD and its own libraries (LLVM, libstdc++, ...), each bound alone at its path.
lvp_json=/usr/share/vulkan/icd.d/lvp_icd.x86_64.json
lvp=$(sed -n 's/.*"library_path": *"\([^"]*\)".*/\1/p' "$lvp_json")
[[ -f "$lvp" ]] || {
    echo "portable_test: lavapipe ($lvp) not found" >&2
    exit 1
}
libvulkan=$(ldconfig -p | awk '$1 == "libvulkan.so.1" && !f {print $NF; f = 1}')
bind=(--ro-bind "$lvp_json" "$lvp_json" --ro-bind "$lvp" "$lvp" --ro-bind "$libvulkan" "$libvulkan")
declare -A bound=()
for f in "$lvp" "$libvulkan" "$build/voxtier-portable"; do
    while read -r path; do
        [[ -n "${bound[$path]:-}" ]] && continue
        bound[$path]=1
        bind+=(--ro-bind "$path" "$path")
    done < <(ldd "$f" | awk '$2 == "=>" && $3 ~ /^\// {print $3} $1 ~ /^\// {print $1}' |
        grep -E '/(ld-linux[^/]*|libc|libm|libdl|libpthread|librt|libresolv|libutil|libmvec)\.so' || true)
done
for path in $(ldd "$lvp" | awk '$2 == "=>" && $3 ~ /^\// {print $3}'); do
    [[ -n "${bound[$path]:-}" ]] && continue
    bound[$path]=1
    bind+=(--ro-bind "$path" "$path")
done

sandbox() {
    bwrap --unshare-all --die-with-parent --clearenv --setenv HOME /tmp \
        --dev /dev --proc /proc --tmpfs /tmp \
        --ro-bind "$work/pkg" /pkg --bind "$work/out" /out --chdir /pkg "${bind[@]}" "$@"
}

# The isolation is real: the project's libraries that the folder carries are not in the sandbox
# at their system paths (bar those lavapipe links itself, such as libstdc++, which a machine with
# a Vulkan driver has too).
hidden=()
for lib in "$work"/pkg/lib/*; do
    name=$(basename "$lib")
    sys=$(ldconfig -p | awk -v n="$name" '$1 == n && !f {print $NF; f = 1}')
    [[ -z "$sys" || -n "${bound[$sys]:-}" ]] && continue
    if ! sandbox --ro-bind /usr/bin/test /usr/bin/test /usr/bin/test ! -e "$sys"; then
        echo "portable_test: $sys is visible in the sandbox" >&2
        exit 1
    fi
    hidden+=("$name")
done
echo "portable_test: hidden in the sandbox: ${hidden[*]}"
[[ " ${hidden[*]}" == *" libembree3"* && " ${hidden[*]}" == *" libtbb"* ]] || {
    echo "portable_test: expected the system's Embree and TBB among them" >&2
    exit 1
}

check_same() { # NAME ARGS...: the ordinary build and the sandboxed folder, byte for byte
    local name="$1"
    shift
    "$build/voxtier" render "$src/scenes/default.json" "$@" -o "$work/out/$name.normal.pam" \
        --ids "$work/out/$name.normal.ids.pam" >/dev/null
    sandbox /pkg/voxtier render /pkg/scenes/default.json "$@" -o "/out/$name.portable.pam" \
        --ids "/out/$name.portable.ids.pam" >"$work/out/$name.log" 2>&1 || {
        cat "$work/out/$name.log" >&2
        exit 1
    }
    cmp "$work/out/$name.normal.pam" "$work/out/$name.portable.pam"
    cmp "$work/out/$name.normal.ids.pam" "$work/out/$name.portable.ids.pam"
    echo "portable_test: $name: identical ($(stat -c %s "$work/out/$name.portable.pam") bytes, ids too)"
}
check_same hybrid
check_same near_vulkan --mode near --near-backend vulkan
grep -q "Vulkan device: llvmpipe" "$work/out/near_vulkan.log" || {
    echo "portable_test: the sandboxed near render did not say it used lavapipe:" >&2
    cat "$work/out/near_vulkan.log" >&2
    exit 1
}

# A machine with no C++ runtime at all (no Mesa driver either): the folder's lib/fallback/ on
# LD_LIBRARY_PATH (what gpu_check.sh sets there) serves it; only the loader family and the
# Vulkan loader (no driver: the CPU reference draws the near tier) are in this sandbox.
minimal=(--ro-bind "$libvulkan" "$libvulkan")
for path in $(ldd "$libvulkan" "$build/voxtier-portable" | awk '$2 == "=>" && $3 ~ /^\// {print $3} $1 ~ /^\// {print $1}' |
    grep -E '/(ld-linux[^/]*|libc|libm)\.so' | sort -u); do
    [[ "$path" == "$libvulkan" ]] || minimal+=(--ro-bind "$path" "$path")
done
if bwrap --unshare-all --clearenv --dev /dev --proc /proc --tmpfs /tmp --ro-bind "$work/pkg" /pkg \
    "${minimal[@]}" /pkg/voxtier --version >/dev/null 2>&1; then
    echo "portable_test: the minimal sandbox has a C++ runtime; it should not" >&2
    exit 1
fi
bwrap --unshare-all --clearenv --setenv LD_LIBRARY_PATH /pkg/lib/fallback --dev /dev --proc /proc \
    --tmpfs /tmp --ro-bind "$work/pkg" /pkg --bind "$work/out" /out "${minimal[@]}" \
    /pkg/voxtier render /pkg/scenes/default.json --near-backend reference -o /out/minimal.pam \
    >"$work/out/minimal.log" 2>&1 || {
    cat "$work/out/minimal.log" >&2
    exit 1
}
cmp "$work/out/hybrid.normal.pam" "$work/out/minimal.pam"
echo "portable_test: without a system C++ runtime, with lib/fallback: identical"

# The Vulkan near tier equals the CPU reference in the sandbox too (in memory, no files).
sandbox /pkg/voxtier check /pkg/scenes/golden/equal_depth.json

# A format that needs OpenImageIO: one line, exit status 2 (the command line), nothing written.
set +e
msg=$(sandbox /pkg/voxtier render /pkg/scenes/default.json -o /out/x.png 2>&1)
rc=$?
set -e
if [[ $rc -ne 2 || $(printf '%s\n' "$msg" | wc -l) -ne 1 || "$msg" != *"without OpenImageIO"* ||
    -e "$work/out/x.png" ]]; then
    echo "portable_test: expected one line and exit status 2 for a .png, got $rc: $msg" >&2
    exit 1
fi
echo "portable_test: a .png is refused: $msg"
