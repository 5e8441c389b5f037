#!/usr/bin/env bash
# Runs each libFuzzer target for a given time (ASan + UBSan, clang).
#   tools/fuzz.sh [SECONDS=60] [TARGET...]     targets: vox_reader_fuzz scene_loader_fuzz
#                                                       snapshot_file_fuzz snapshot_pack_fuzz
# Seeds: fuzz/corpus/<kind>/ (hand-made malformed fixtures) plus the real files in scenes/.
# The growing corpus and crash artefacts stay in fuzz-out/<target>/ (git-ignored).
set -euo pipefail
cd "$(dirname "$0")/.."
seconds="${1:-60}"
shift || true
targets=("$@")
[[ ${#targets[@]} -eq 0 ]] && targets=(vox_reader_fuzz scene_loader_fuzz snapshot_file_fuzz snapshot_pack_fuzz)

bash tools/setup.sh --fuzz
cmake --preset fuzz >/dev/null
cmake --build build-fuzz --target "${targets[@]}"

status=0
for t in "${targets[@]}"; do
    work="fuzz-out/$t"
    mkdir -p "$work/corpus" "$work/seeds" "$work/artifacts"
    case "$t" in
    vox_reader_fuzz)
        cp fuzz/corpus/vox/* "$work/seeds/"
        find scenes/vox -name '*.vox' -size -400k -exec cp {} "$work/seeds/" \;
        dict=()
        ;;
    scene_loader_fuzz)
        cp fuzz/corpus/scene/* "$work/seeds/"
        find scenes -name '*.json' -not -path 'scenes/vox/*' -exec cp {} "$work/seeds/" \;
        dict=()
        ;;
    snapshot_file_fuzz)
        cp fuzz/corpus/snapshot/* "$work/seeds/"
        dict=()
        ;;
    snapshot_pack_fuzz)
        cp fuzz/corpus/pack/* "$work/seeds/"
        dict=()
        ;;
    *) echo "unknown target $t" >&2; exit 2 ;;
    esac
    echo "== $t for ${seconds}s"
    if ! "build-fuzz/fuzz/$t" "$work/corpus" "$work/seeds" -max_total_time="$seconds" -timeout=10 \
        -rss_limit_mb=4096 -max_len=65536 -print_final_stats=1 -artifact_prefix="$work/artifacts/" \
        "${dict[@]}" >"$work/log.txt" 2>&1; then
        status=1
        echo "$t: FAILED (see $work/log.txt and $work/artifacts/)"
    fi
    grep -E "stat::number_of_executed_units|stat::peak_rss_mb|Done [0-9]+ runs" "$work/log.txt" || true
    grep -E "ERROR: |SUMMARY: " "$work/log.txt" || echo "$t: no crash, no sanitizer report"
done
exit $status
