#!/usr/bin/env bash
# Installs exactly the Debian packages voxtier needs to build, render and test.
# Idempotent: packages already present are not touched, so a second run takes a second.
# Usage: tools/setup.sh            (build + run + test packages)
#        tools/setup.sh --fuzz     (also clang's libFuzzer/sanitizer runtime)
set -euo pipefail

packages=(
    # build
    cmake ninja-build g++ pkgconf
    libembree-dev libglm-dev libopenimageio-dev libtbb-dev
    libvulkan-dev glslang-tools nlohmann-json3-dev libcli11-dev
    # the far blit's SIMD kernel with run-time dispatch (Highway)
    libhwy-dev
    # the bench report's template engine (header-only)
    libkainjow-mustache-dev
    # Debian's OpenImageIO CMake config (OpenImageIOTargets.cmake) refuses to load unless the
    # command-line tools it exports (/usr/bin/iconvert, ...) exist; they live in this package.
    openimageio-tools
    # run: the Vulkan driver (Mesa lavapipe works without a GPU)
    mesa-vulkan-drivers
    # tests
    libgtest-dev vulkan-validationlayers
    # tests: the portable folder run isolated (tests/portable_test.sh)
    bubblewrap
    # tests: tools/validate_scenes.py (scene files against docs/scene.schema.json)
    python3-jsonschema
    # bench plots
    gnuplot-nox
    # the formatting rule CI checks (tools/format.sh --check): Debian 12's clang-format 14
    clang-format
)
if [[ "${1:-}" == "--fuzz" ]]; then
    packages+=(clang libclang-rt-14-dev llvm)
fi

missing=()
for p in "${packages[@]}"; do
    if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep "ok installed" >/dev/null; then
        missing+=("$p")
    fi
done
[[ ${#missing[@]} -eq 0 ]] && exit 0

echo "setup: installing ${missing[*]}" >&2
sudo=""
if [[ $(id -u) -ne 0 ]]; then
    command -v sudo >/dev/null || { echo "setup: need root (or sudo) to install: ${missing[*]}" >&2; exit 1; }
    sudo="sudo"
fi
export DEBIAN_FRONTEND=noninteractive
# Try without refreshing the package lists first (fast, offline-friendly); refresh once on failure.
if ! $sudo apt-get install -y --no-install-recommends "${missing[@]}" >/tmp/voxtier-setup.log 2>&1; then
    $sudo apt-get update >>/tmp/voxtier-setup.log 2>&1 || true
    $sudo apt-get install -y --no-install-recommends "${missing[@]}" >>/tmp/voxtier-setup.log 2>&1 || {
        tail -n 20 /tmp/voxtier-setup.log >&2
        echo "setup: apt-get failed (log: /tmp/voxtier-setup.log)" >&2
        exit 1
    }
fi
