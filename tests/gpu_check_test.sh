#!/usr/bin/env bash
# tools/gpu_check.sh --short --profile against this build: it must pass its identity check, name
# the Vulkan device, and write report.md and results.csv with the identity rows (0 differing
# pixels), the bench's rows and the profile's pass-by-pass rows (a small tank army curve here), and
# the far pass cut three ways (hybrid and all far, moving and still), placement and records
# comparisons and the error budget's hybrid on the curve's largest army.
# Usage: gpu_check_test.sh VOXTIER SOURCE_DIR
set -euo pipefail
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
VOXTIER="$1" VOXTIER_SCENES="$2/scenes" VOXTIER_PROFILE_COUNTS=40,80 \
    bash "$2/tools/gpu_check.sh" --short --profile "$work/out" |
    tee "$work/log"
fail() {
    echo "gpu_check_test: $*" >&2
    exit 1
}
grep -q "^gpu_check: Vulkan device used: ." "$work/log" || fail "no 'Vulkan device used' line"
for f in report.md results.csv identity_near.csv bench/results.csv; do
    [[ -s "$work/out/$f" ]] || fail "$f missing or empty"
done
grep -q "^| golden/equal_depth.json | 0.000 |.*| 0 | 0 | 0 | identical |" "$work/out/report.md" ||
    fail "report.md lacks the identity row of golden/equal_depth.json"
grep -q "^- Vulkan device: \*\*.\+\*\*" "$work/out/report.md" || fail "report.md names no device"
grep -q "^identity_near,golden/equal_depth.json,t=0.000 id_diffs,0,pixels" "$work/out/results.csv" ||
    fail "results.csv lacks the identity rows"
grep -q "^bench,street,hybrid.* in_motion_far_entities,[0-9.]\+,count" "$work/out/results.csv" ||
    fail "results.csv has no far sprites in motion for the street's hybrid"
grep -q "^bench,street,hybrid.*in_motion_ms,[0-9.]\+,ms" "$work/out/results.csv" ||
    fail "results.csv lacks the hybrid's in-motion ms"
# The all-near Vulkan frame timed on the device without its readback, beside the warm frame.
grep -q "^bench,street,near_vulkan device_frame_ms,[0-9.]*[1-9][0-9.]*,ms" "$work/out/results.csv" ||
    fail "results.csv lacks near_vulkan's device frame"
grep -q "^## Where the time goes, pass by pass" "$work/out/report.md" || fail "report.md has no profile"
# The device timed the near tier's draw of the tank army (lavapipe has timestamps): a positive
# gpu_draw_ms in the profile rows of near_vulkan.
grep -q "^profile,tank_army (80 entities),near_vulkan gpu_draw_ms,[0-9.]*[1-9][0-9.]*,ms" \
    "$work/out/results.csv" || fail "results.csv lacks a timed near draw in the profile"
# The bench's frames in motion split the same way (means per frame), the hybrid's far tier among
# its parts.
grep -q "^## Where the time goes in motion, pass by pass" "$work/out/report.md" ||
    fail "report.md has no in-motion profile"
grep -q "^profile_in_motion,street,hybrid far_ms,[0-9.]*[1-9][0-9.]*,ms" "$work/out/results.csv" ||
    fail "results.csv lacks the hybrid's far tier in motion"
grep -q "^profile_in_motion,street,near_vulkan host_wait_ms,[0-9.]*[1-9][0-9.]*,ms" \
    "$work/out/results.csv" || fail "results.csv lacks all-near Vulkan's wait in motion"
# The far pass's coarse and fine tiles and the pass cut by sprite, and direct writes against
# staged uploads, on the curve's largest army: each drew the same last frame, and each has its rows.
grep -q "^## The far pass: 80 tanks" "$work/out/report.md" || fail "report.md has no far-tiles table"
grep -q "Frame 23, coarse against fine: identical; coarse against sprites: identical; all far, coarse against fine: identical; all far, coarse against sprites: identical." \
    "$work/out/report.md" || fail "the far pass cut three ways was not found identical"
# All far, cut each way moving and the default cut under a still camera: timed far passes.
for item in "far coarse" "far fine" "far sprites" "far still"; do
    grep -q "^far_tiles,tank_army_80,$item gpu_far_ms,[0-9.]*[1-9][0-9.]*,ms" "$work/out/results.csv" ||
        fail "results.csv lacks the far pass of the render '$item'"
done
for item in "hybrid_gpu_far fine" "hybrid_gpu_far sprites"; do
    grep -q "^far_tiles,tank_army_80,$item gpu_far_ms,[0-9.]*[1-9][0-9.]*,ms" "$work/out/results.csv" ||
        fail "results.csv lacks the far pass of the render '$item'"
done
for c in host_setup_ms host_select_ms far_ms; do
    grep -q "^far_tiles,tank_army_80,hybrid_gpu_far coarse $c,[0-9.]*[1-9][0-9.]*,ms" "$work/out/results.csv" ||
        fail "results.csv lacks the far-tiles render's $c"
done
grep -q "| render | frames | frame in flight | set-up | select | far tier | of which lookups and bakes" \
    "$work/out/report.md" || fail "the far-tiles table lacks the frame's host parts"
grep -q "Frame 23, direct against staged: identical." "$work/out/report.md" ||
    fail "direct writes and staged uploads were not found identical"
grep -q "^placement,tank_army_80,near_vulkan staged host_record_sprites_ms,[0-9.]*[1-9][0-9.]*,ms" \
    "$work/out/results.csv" || fail "results.csv lacks the staged run's sprite records"
# The sprite records laid out both ways (--near-records): the same image, each its rows.
grep -q "Frame 23, drawn against given: identical." "$work/out/report.md" ||
    fail "the records in the draw order and in entity order were not found identical"
for l in drawn given; do
    grep -q "^records,tank_army_80,near_vulkan records $l host_record_sprites_ms,[0-9.]*[1-9][0-9.]*,ms" \
        "$work/out/results.csv" || fail "results.csv lacks the sprite records laid out $l"
done
# The army under the error budget, hybrid, beside all-near: its rows and the ratio.
grep -q "^## The error budget: 80 tanks, hybrid against all-near Vulkan" "$work/out/report.md" ||
    fail "report.md has no error-budget table"
for item in "hybrid_budget host_select_ms" "hybrid_budget frame_ms" "near_vulkan frame_ms"; do
    grep -q "^error_budget,tank_army_80,$item,[0-9.]*[1-9][0-9.]*,ms" "$work/out/results.csv" ||
        fail "results.csv lacks the error-budget row '$item'"
done
# The selection's parts beside it, each a row (a few entities' steps may round to 0).
grep -q "| select | of which inputs | of which tiers | of which views | of which choices.*| cache questions |" \
    "$work/out/report.md" || fail "the error-budget table lacks the selection's parts"
for c in inputs tiers views choices cost_bound predictions; do
    grep -q "^error_budget,tank_army_80,hybrid_budget host_select_${c}_ms,[0-9.e+-]*,ms" \
        "$work/out/results.csv" || fail "results.csv lacks the error budget's selection part $c"
done
grep -q "^error_budget,tank_army_80,hybrid_budget speedup_vs_all_near_vulkan,[0-9.]*[1-9][0-9.]*,x" \
    "$work/out/results.csv" || fail "results.csv lacks the error budget's speed-up"
echo "gpu_check_test: ok"
