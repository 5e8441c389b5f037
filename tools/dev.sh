#!/usr/bin/env bash
# The README's Quick start in one script.
#   tools/dev.sh render [ARGS]    set up, build the CLI, render scenes/default.json -> out/default.png
#   tools/dev.sh test [ARGS]      set up, build, run the whole test suite (what .ci/run calls)
#   tools/dev.sh build            set up and build everything
#   tools/dev.sh fuzz [SECONDS]   run each libFuzzer target for SECONDS (tools/fuzz.sh)
#   tools/dev.sh format [--check] clang-format every C++ source (tools/format.sh; CI checks)
# VOXTIER_PRESET=asan|tsan selects a sanitizer build (CMakePresets.json) in build-<preset>.
set -euo pipefail
cd "$(dirname "$0")/.."

cmd="${1:-render}"
shift || true
[[ "$cmd" == fuzz ]] && exec bash tools/fuzz.sh "$@"
[[ "$cmd" == format ]] && { bash tools/setup.sh; exec bash tools/format.sh "$@"; }

bash tools/setup.sh

preset="${VOXTIER_PRESET:-default}"
run_tests=()
case "$preset" in
default) build_dir="${VOXTIER_BUILD_DIR:-build}" ;;
asan)
    build_dir="build-asan"
    # The preset links with --as-needed, which Debian's GCC gives the linker by default but not
    # under -fsanitize: without it 68 of 70 test executables loaded OpenImageIO and its ~250
    # libraries, ~1.6 s a test process under ASan (the suite: 1,258 s, with it 802;
    # docs/decisions/ci-time.md).
    # Mesa's lavapipe and the loader keep a few allocations alive until exit: report leaks
    # only where the stack touches our code (tools/lsan.supp lists the driver frames).
    # intercept_tls_get_addr=0: GCC 12's LeakSanitizer misreads a dynamically loaded library's
    # thread-local block (google/sanitizers#1322) and its tracer crashes at exit ("Tracer caught
    # signal 11", a DTLS range of 0x2ca3-0x1000003da5) in a CLI that loaded OpenImageIO's module
    # (image_files/detail/image_library_module.hpp) to write a .png. Without the interceptor LSan
    # does not scan such blocks; voxtier's own thread-locals are in the programs' static TLS.
    export ASAN_OPTIONS="detect_leaks=1:abort_on_error=1:strict_string_checks=1:check_initialization_order=1:intercept_tls_get_addr=0"
    export LSAN_OPTIONS="suppressions=$PWD/tools/lsan.supp:print_suppressions=0"
    export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1"
    ;;
tsan)
    build_dir="build-tsan"
    export TSAN_OPTIONS="halt_on_error=1:second_deadlock_stack=1:suppressions=$PWD/tools/tsan.supp"
    # Debian's libtbb is not built with -fsanitize=thread, so TSan cannot see the happens-before
    # edge between a task being spawned and a TBB worker running it, and flags every
    # parallel_for body (a race-free 15-line parallel_for program is flagged too). On one CPU
    # TBB starts no workers; the threads the code and tests create themselves (concurrent cache
    # requests, edits beside renders, the Vulkan driver's threads) still interleave and are
    # checked. TSan reasons about happens-before, not timing, so one CPU loses no report there.
    run_tests=(taskset -c 0)
    ;;
*) echo "unknown VOXTIER_PRESET '$preset' (default, asan, tsan)" >&2; exit 2 ;;
esac
if [[ ! -f "$build_dir/CMakeCache.txt" ]]; then
    if [[ "$preset" == default ]]; then
        cmake -S . -B "$build_dir" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo >/dev/null
    else
        cmake --preset "$preset" >/dev/null
    fi
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
    "${run_tests[@]}" ctest --test-dir "$build_dir" --output-on-failure -j "$(nproc)" "$@"
    ;;
*)
    echo "usage: tools/dev.sh render|test|build|fuzz|format [args...]" >&2
    exit 2
    ;;
esac
