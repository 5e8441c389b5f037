#!/usr/bin/env bash
# clang-format over every C++ source the repository tracks, with the committed .clang-format.
#   tools/format.sh           rewrite the files in place
#   tools/format.sh --check   change nothing; exit 1 and list the files that differ (what CI runs)
# The rule is Debian 12's clang-format (14), the one tools/setup.sh installs: another major
# version formats some constructs differently, so the check pins it.
set -euo pipefail
cd "$(dirname "$0")/.."
bin="${CLANG_FORMAT:-clang-format}"
command -v "$bin" >/dev/null || { echo "format: $bin not found (tools/setup.sh installs it)" >&2; exit 1; }
version=$("$bin" --version | sed -n 's/.*version \([0-9]*\)\..*/\1/p')
if [[ "$version" != 14 ]]; then
    echo "format: $bin is version ${version:-unknown}; the committed formatting is clang-format 14's" >&2
    exit 1
fi
mapfile -t files < <(git ls-files '*.cpp' '*.hpp' '*.h')
if [[ "${1:-}" == "--check" ]]; then
    bad=()
    for f in "${files[@]}"; do
        "$bin" --dry-run --Werror "$f" >/dev/null 2>&1 || bad+=("$f")
    done
    if [[ ${#bad[@]} -gt 0 ]]; then
        echo "format: ${#bad[@]} file(s) differ from .clang-format (run bash tools/format.sh):" >&2
        printf '  %s\n' "${bad[@]}" >&2
        exit 1
    fi
    echo "format: ${#files[@]} files clean" >&2
else
    "$bin" -i "${files[@]}"
fi
