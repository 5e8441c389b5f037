#!/usr/bin/env bash
# The GPU check: on the machine it runs on, with the Vulkan device that machine has,
#   (a) identity: the Vulkan near tier draws the golden scenes and the default scene exactly as
#       the CPU reference does (`voxtier check`: colour, depth, id compared in memory, 0 pixels
#       may differ), and, where the binary has `render --far-backend`, the Vulkan far pass
#       exactly as the CPU blit (colour and ids, byte for byte as .pam);
#   (b) speed: `voxtier bench` on the street, tank army and RTS pan scenes in motion at the
#       1 vpx error budget (48 frames, 6 of them the cold start).
# It writes OUTDIR/report.md (device, driver, the identity results, the bench tables with
# absolute ms and ratios) and OUTDIR/results.csv (the same figures, one row each), and keeps
# the commands' own output beside them (identity_near.csv, bench/, logs/).
#
# Runs from the portable folder (tools/portable.sh: ./gpu_check.sh there), from a source tree
# with a build (tools/gpu_check.sh uses build/voxtier), or with VOXTIER=/path/to/voxtier.
# Under 6 minutes on a GPU; on lavapipe (2 CPU cores) the full run takes much longer
# (CONTRACT.md §8). Exit status 1 when an identity check fails or a command fails.
#
# Usage: gpu_check.sh [--short] [--profile] [OUTDIR]      (OUTDIR default: gpu-check)
#   --short   one golden scene and one small bench (what CI runs, tests/CMakeLists.txt)
#   --profile also where each frame's time goes, pass by pass (the device's timestamps and the
#             host's parts: the gpu_*_ms and host_*_ms figures): for the bench scenes in motion,
#             and the tank army at 2,000, 20,000 and 100,000 entities (VOXTIER_PROFILE_COUNTS
#             overrides them), in report.md and results.csv; and the far pass cut three ways
#             (--far-tiles coarse, fine, sprites) on the moving tank army's hybrid and all far
#             at the largest count, all far under a still camera too, the same army's hybrid
#             under the error budget (1 vpx: most tanks far) beside its all-near frames,
#             and direct writes against staged uploads on those all-near frames, images compared
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
short=0
profile=0
out=""
while [[ $# -gt 0 ]]; do
    case "$1" in
    --short)
        short=1
        shift
        ;;
    --profile)
        profile=1
        shift
        ;;
    -h | --help)
        sed -n '2,25p' "$0"
        exit 0
        ;;
    -*)
        echo "gpu_check: unknown option '$1' (see --help)" >&2
        exit 2
        ;;
    *)
        out="$1"
        shift
        ;;
    esac
done

# The binary and the scenes: the portable folder's, else the source tree's.
if [[ -n "${VOXTIER:-}" ]]; then
    bin="$VOXTIER"
    scenes="${VOXTIER_SCENES:-$here/../scenes}"
elif [[ -x "$here/voxtier" && -d "$here/scenes" ]]; then
    bin="$here/voxtier"
    scenes="$here/scenes"
else
    bin="$here/../build/voxtier"
    scenes="$here/../scenes"
fi
[[ -x "$bin" ]] || {
    echo "gpu_check: no voxtier at $bin (build it, or set VOXTIER)" >&2
    exit 1
}
scenes="$(cd "$scenes" && pwd)"
out="${out:-gpu-check}"
mkdir -p "$out/logs"
out="$(cd "$out" && pwd)"

# The portable folder's C++ runtime, only where the machine has none (tools/portable.sh).
if [[ -d "$(dirname "$bin")/lib/fallback" ]] && ! ldconfig -p 2>/dev/null | grep 'libstdc++\.so\.6 ' >/dev/null; then
    LD_LIBRARY_PATH="$(dirname "$bin")/lib/fallback${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
    export LD_LIBRARY_PATH
fi
# The machine brings its own Vulkan loader; say so in one line when it lacks one.
if ! "$bin" --version >/dev/null 2>"$out/logs/version.err"; then
    echo "gpu_check: $bin does not start: $(head -1 "$out/logs/version.err")" >&2
    if grep -q libvulkan "$out/logs/version.err"; then
        echo "gpu_check: this machine has no Vulkan loader (libvulkan.so.1): install one (Debian/Ubuntu: libvulkan1)" >&2
    fi
    exit 1
fi
# An NVIDIA driver that the loader does not list (its manifest outside the loader's search
# path, as on the device machines here): point the loader at it.
nvidia_icd=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
if [[ -z "${VK_DRIVER_FILES:-}${VK_ICD_FILENAMES:-}" && -f "$nvidia_icd" ]]; then
    export VK_DRIVER_FILES="$nvidia_icd"
fi

start=$(date +%s)
failed=0
version="$("$bin" --version)"
echo "gpu_check: $version ($bin), scenes $scenes, output $out"

# --- (a) identity --------------------------------------------------------------------------
if ((short)); then
    golden=("$scenes/golden/equal_depth.json")
else
    golden=("$scenes"/golden/*.json "$scenes/default.json")
fi
set +e
"$bin" check "${golden[@]}" --csv "$out/identity_near.csv" 2>&1 | tee "$out/logs/check.log"
near_rc=${PIPESTATUS[0]}
set -e
device="$(sed -n 's/^Vulkan device: //p' "$out/logs/check.log" | head -1)"
if [[ -z "$device" ]]; then
    echo "gpu_check: no Vulkan device: $(tail -1 "$out/logs/check.log")" >&2
    exit 1
fi
echo "gpu_check: Vulkan device used: $device"
((near_rc == 0)) || failed=1

# Vulkan far == CPU far, where the binary has the far pass on Vulkan (issue 26).
far_rows=""
if "$bin" render --help 2>/dev/null | grep -- '--far-backend' >/dev/null; then
    mkdir -p "$out/far"
    for s in "${golden[@]}"; do
        name=$(basename "$s" .json)
        colour=identical ids=identical
        for backend in cpu vulkan; do
            if ! "$bin" render "$s" --mode far --far-backend "$backend" --no-cost-bound \
                -o "$out/far/$name.$backend.pam" --ids "$out/far/$name.$backend.ids.pam" \
                >>"$out/logs/far.log" 2>&1; then
                colour="render failed ($backend, logs/far.log)" ids=-
            fi
        done
        if [[ $ids != - ]]; then
            cmp -s "$out/far/$name.cpu.pam" "$out/far/$name.vulkan.pam" || colour=different
            cmp -s "$out/far/$name.cpu.ids.pam" "$out/far/$name.vulkan.ids.pam" || ids=different
        fi
        [[ $colour == identical && $ids == identical ]] || failed=1
        echo "$s: Vulkan far vs CPU far: colour $colour, ids $ids"
        far_rows+="$s,$colour,$ids"$'\n'
    done
    rm -f "$out"/far/*.pam
else
    echo "gpu_check: Vulkan far vs CPU far: skipped (this voxtier has no render --far-backend)"
fi

# --- (b) the bench -------------------------------------------------------------------------
if ((short)); then
    bench_args=("$scenes/bench/street.json" --smoke --no-sweeps --no-scaling --budget 1
        --motion-frames 4 --motion-warmup 2)
else
    bench_args=("$scenes/bench/street.json" "$scenes/bench/tank_army.json"
        "$scenes/bench/rts_pan.json" --quick --no-sweeps --no-scaling --budget 1
        --motion-frames 48 --motion-warmup 6)
fi
# The GPU's clocks while it works (nvidia-smi, where the machine has one): a GPU that idles
# between frames, as it does while the bench draws the CPU modes between its Vulkan frames, runs
# them at a fraction of its clock. The phases' times mark which samples belong to what.
clocks_pid=""
if command -v nvidia-smi >/dev/null && nvidia-smi -L >/dev/null 2>&1; then
    nvidia-smi --query-gpu=timestamp,clocks.sm,utilization.gpu --format=csv,noheader,nounits \
        -lms 100 >"$out/logs/clocks.csv" 2>/dev/null &
    clocks_pid=$!
fi
phase() { echo "$(date +%s.%N) $1" >>"$out/logs/phases.txt"; }
phase bench
bench_start=$(date +%s)
set +e
"$bin" bench "${bench_args[@]}" -o "$out/bench" >"$out/logs/bench.log" 2>&1
bench_rc=$?
set -e
bench_s=$(($(date +%s) - bench_start))
if ((bench_rc != 0)); then
    echo "gpu_check: the bench failed (exit $bench_rc): $(tail -1 "$out/logs/bench.log")" >&2
    failed=1
fi
# --- (c) the profile: the tank army's entity curve, every mode, with its per-pass figures ------
if ((profile)); then
    set +e
    "$bin" bench "$scenes/bench/tank_army.json" --quick --no-sweeps --far-backend vulkan \
        --entity-counts "${VOXTIER_PROFILE_COUNTS:-2000,20000,100000}" -o "$out/tank_curve" >"$out/logs/tank_curve.log" 2>&1
    curve_rc=$?
    set -e
    if ((curve_rc != 0)); then
        echo "gpu_check: the tank army curve failed (exit $curve_rc): $(tail -1 "$out/logs/tank_curve.log")" >&2
        failed=1
    fi
    # All-near Vulkan along each bench scene's path with frames in flight, as a game draws: frame
    # k+1 is set up, recorded and on the device while frame k is read back (render --frames).
    phase in_flight
    mkdir -p "$out/in_flight"
    for s in street tank_army rts_pan; do
        if ! "$bin" render "$scenes/bench/$s.json" --mode near --near-backend vulkan --frames 0:47 \
            --csv "$out/in_flight/$s.csv" -o "$out/in_flight/$s.pam" >>"$out/logs/in_flight.log" 2>&1; then
            echo "gpu_check: the in-flight render of $s failed: $(tail -1 "$out/logs/in_flight.log")" >&2
            failed=1
        fi
        rm -f "$out/in_flight/$s"_*.pam
    done
    # The far pass cut three ways (--far-tiles: coarse and fine tiles, or by sprite; the same
    # image) on the moving tank army at the curve's largest count (100,000 by default) in flight,
    # the hybrid with the far pass on Vulkan: frames 0:23, the last one compared.
    phase far_tiles
    mkdir -p "$out/far_tiles"
    # Frame 23 of the renders far_tiles/A and far_tiles/B, compared byte for byte: "identical" or
    # "DIFFERENT" into far_tiles/RESULT (a failed check), nothing where a render is missing.
    same_last_frame() {
        local a="$out/far_tiles/${1}_0023.pam" b="$out/far_tiles/${2}_0023.pam"
        if [[ -f "$a" && -f "$b" ]]; then
            if cmp -s "$a" "$b"; then
                echo identical >"$out/far_tiles/$3"
            else
                echo DIFFERENT >"$out/far_tiles/$3"
                echo "gpu_check: $4 drew different images" >&2
                failed=1
            fi
        fi
    }
    big=$(tr ',' '\n' <<<"${VOXTIER_PROFILE_COUNTS:-2000,20000,100000}" | sort -n | tail -1)
    army="$out/far_tiles/tank_army_$big.json"
    sed "s/\"count\": 2000,/\"count\": $big,/" "$scenes/bench/tank_army.json" >"$army"
    for t in coarse fine sprites; do
        if ! "$bin" render "$army" --mode hybrid --far-backend vulkan \
            --far-tiles "$t" --frames 0:23 --csv "$out/far_tiles/$t.csv" -o "$out/far_tiles/$t.pam" \
            >>"$out/logs/far_tiles.log" 2>&1; then
            echo "gpu_check: the far-tiles render ($t) failed: $(tail -1 "$out/logs/far_tiles.log")" >&2
            failed=1
        fi
    done
    same_last_frame coarse fine identity.txt "the far pass's coarse and fine tiles"
    same_last_frame coarse sprites sprites_identity.txt "the far pass's coarse tiles and sprites"
    rm -f "$out/far_tiles/"*_00*.pam
    # The same army all far, moving, cut each way: every tank through the far pass, whose
    # crowded tiles a pixel's walk over nearest-first sprites cuts short (stop 49) and the pass
    # cut by sprite covers rectangle by rectangle (stop 50); then under a still camera (its camera
    # path removed), where a frame keeps the far pass's records, order and tile lists that still
    # hold (the device's default cut).
    for t in coarse fine sprites; do
        if ! "$bin" render "$army" --mode far --far-backend vulkan \
            --far-tiles "$t" --frames 0:23 --csv "$out/far_tiles/far_$t.csv" \
            -o "$out/far_tiles/far_$t.pam" >>"$out/logs/far_tiles.log" 2>&1; then
            echo "gpu_check: the all-far render ($t) failed: $(tail -1 "$out/logs/far_tiles.log")" >&2
            failed=1
        fi
    done
    same_last_frame far_coarse far_fine far_identity.txt "the all-far coarse and fine tiles"
    same_last_frame far_coarse far_sprites far_sprites_identity.txt \
        "the all-far coarse tiles and sprites"
    rm -f "$out/far_tiles/"*_00*.pam
    # A variant of the army, its JSON changed by the Python statement EDIT on `d`, rendered
    # with OPTIONS over frames 0:23 into far_tiles/NAME.csv; skipped without python3.
    # Usage: render_army_variant NAME LABEL EDIT OPTIONS...
    render_army_variant() {
        local name=$1 label=$2 edit=$3
        shift 3
        local scene="$out/far_tiles/tank_army_${big}_$name.json"
        command -v python3 >/dev/null &&
            python3 -c "import json, sys; d = json.load(open(sys.argv[1])); $edit; json.dump(d, open(sys.argv[2], 'w'))" \
                "$army" "$scene" || return 0
        if ! "$bin" render "$scene" "$@" --frames 0:23 --csv "$out/far_tiles/$name.csv" \
            -o "$out/far_tiles/$name.pam" >>"$out/logs/far_tiles.log" 2>&1; then
            echo "gpu_check: the $label render failed: $(tail -1 "$out/logs/far_tiles.log")" >&2
            failed=1
        fi
        rm -f "$out/far_tiles/${name}"_00*.pam
    }
    render_army_variant far_still "still all-far" 'd.pop("camera_path", None)' \
        --mode far --far-backend vulkan
    # The same army under the error budget (selector metric error_budget, 1 vpx, the view
    # ladder), hybrid with the far pass on Vulkan, moving: most tanks go far (on the 2-core
    # development machine, 81,657 of 85,875), where the bench's error_px sends ~10 %; beside
    # the all-near renders below, what the hybrid gains on this device.
    render_army_variant budget error-budget \
        'd["selector"] = {"metric": "error_budget", "budget_vpx": 1.0}' \
        --mode hybrid --far-backend vulkan
    # Where the host writes what the shaders read: directly into device-local memory through the
    # BAR where the device offers it (the policy's choice), or staged and copied by the device
    # (VOXTIER_FORCE_STAGING=1): the same army all-near in flight, frames 0:23 each.
    phase placement
    for p in direct staged; do
        if ! env $([[ $p == staged ]] && echo VOXTIER_FORCE_STAGING=1) "$bin" render \
            "$army" --mode near --near-backend vulkan --frames 0:23 \
            --csv "$out/far_tiles/near_$p.csv" -o "$out/far_tiles/near_$p.pam" \
            >>"$out/logs/placement.log" 2>&1; then
            echo "gpu_check: the placement render ($p) failed: $(tail -1 "$out/logs/placement.log")" >&2
            failed=1
        fi
    done
    same_last_frame near_direct near_staged placement_identity.txt "direct writes and staged uploads"
    # Where the near tier lays its sprite records (--near-records, the same image): at their places
    # in the draw order (the host gathers them from the sprites) or in entity order (the host reads
    # the sprites in sequence, the device finds each through its place). The default is `drawn`
    # until a GPU's figures say otherwise: on lavapipe `given` shortened the host's records by
    # 1.0-1.6 ms at 100,000 tanks and lengthened the device's frame by 0-12 %.
    phase records
    for l in drawn given; do
        if ! "$bin" render "$army" --mode near --near-backend vulkan --near-records "$l" \
            --frames 0:23 --csv "$out/far_tiles/records_$l.csv" -o "$out/far_tiles/records_$l.pam" \
            >>"$out/logs/records.log" 2>&1; then
            echo "gpu_check: the records render ($l) failed: $(tail -1 "$out/logs/records.log")" >&2
            failed=1
        fi
    done
    same_last_frame records_drawn records_given records_identity.txt "records drawn and given"
fi
phase end
[[ -n "$clocks_pid" ]] && kill "$clocks_pid" 2>/dev/null
total_s=$(($(date +%s) - start))

# --- report.md and results.csv -------------------------------------------------------------
export GC_OUT="$out" GC_DEVICE="$device" GC_VERSION="$version" GC_FAR_ROWS="$far_rows"
export GC_TOTAL_S="$total_s" GC_BENCH_S="$bench_s" GC_SHORT="$short" GC_FAILED="$failed"
export GC_PROFILE="$profile" GC_BIG="${big:-}"
export GC_BENCH_CMD="voxtier bench ${bench_args[*]//$scenes\//scenes/}"
if command -v python3 >/dev/null; then
    python3 - <<'PY'
import csv, os, platform, datetime
out = os.environ["GC_OUT"]
def middle(values):
    """A median as the report takes it: the upper middle of the sorted values."""
    return sorted(values)[len(values) // 2]
def fmt(v):
    try:
        return f"{float(v):.3g}" if abs(float(v)) < 100 else f"{float(v):.0f}"
    except ValueError:
        return v or "–"
rows = []  # results.csv: section, scene, item, value, unit
lines = ["# voxtier GPU check", ""]
lines += [f"- Date: {datetime.datetime.now(datetime.timezone.utc):%Y-%m-%d %H:%M} UTC; host {platform.node()}, {os.cpu_count()} CPUs",
          f"- Binary: {os.environ['GC_VERSION']}",
          f"- Vulkan device: **{os.environ['GC_DEVICE']}**",
          f"- Run: {'--short (CI)' if os.environ['GC_SHORT'] == '1' else 'full'}; "
          f"{os.environ['GC_TOTAL_S']} s in all, the bench {os.environ['GC_BENCH_S']} s",
          f"- Result: {'**FAILED**' if os.environ['GC_FAILED'] == '1' else 'every identity check passed'}", ""]
rows.append(("run", "", "device", os.environ["GC_DEVICE"], ""))
rows.append(("run", "", "total_s", os.environ["GC_TOTAL_S"], "s"))
lines += ["## Identity: Vulkan near vs CPU reference (`voxtier check`)", "",
          "| scene | time (s) | size | drawn px | colour ≠ | depth ≠ | id ≠ | result |", "|---|---|---|---|---|---|---|---|"]
with open(os.path.join(out, "identity_near.csv")) as f:
    for r in csv.DictReader(f):
        scene = r["scene"].split("/scenes/")[-1]
        lines.append(f"| {scene} | {float(r['time']):.3f} | {r['width']}×{r['height']} | {r['drawn_pixels']} | "
                     f"{r['colour_diffs']} | {r['depth_diffs']} | {r['id_diffs']} | {r['result']} |")
        for k in ("colour_diffs", "depth_diffs", "id_diffs"):
            rows.append(("identity_near", scene, f"t={float(r['time']):.3f} {k}", r[k], "pixels"))
lines.append("")
far = [l.split(",") for l in os.environ["GC_FAR_ROWS"].splitlines() if l]
lines += ["## Identity: Vulkan far vs CPU far", ""]
if far:
    lines += ["| scene | colour | ids |", "|---|---|---|"]
    for s, c, i in far:
        scene = s.split("/scenes/")[-1]
        lines.append(f"| {scene} | {c} | {i} |")
        rows.append(("identity_far", scene, "colour", c, ""))
        rows.append(("identity_far", scene, "ids", i, ""))
else:
    lines.append("Skipped: this voxtier has no `render --far-backend` (the Vulkan far pass, issue 26).")
lines.append("")
bench_csv = os.path.join(out, "bench", "results.csv")
lines += ["## Bench in motion", "", f"`{os.environ['GC_BENCH_CMD']}`", ""]
if os.path.exists(bench_csv):
    with open(bench_csv) as f:
        bench = [r for r in csv.DictReader(f) if r.get("group") == "modes"]
    cols = [("in_motion_ms", "in motion median (ms)", "ms"), ("in_motion_p90_ms", "p90 (ms)", "ms"),
            ("in_motion_cold_ms", "cold start (ms)", "ms"),
            ("in_motion_all_near_vulkan_ms", "all-near Vulkan (ms)", "ms"),
            ("in_motion_speedup_vs_all_near_vulkan", "× vs all-near Vulkan", "x"),
            ("in_motion_all_near_reference_ms", "all-near CPU reference (ms)", "ms"),
            ("in_motion_speedup_vs_all_near_reference", "× vs all-near reference", "x"),
            ("near_backend", "near drawn by", ""), ("in_motion_psnr_min", "min PSNR (dB)", "dB"),
            ("in_motion_far_entities", "far sprites in motion (0: all near, or the far tier held near)",
             "count"),
            ("frame_ms", "warm frame (ms)", "ms"),
            ("device_frame_ms", "warm frame on the device, no readback (ms; 0: a CPU tier)", "ms")]
    lines += ["| scene | mode | " + " | ".join(c[1] for c in cols) + " |", "|---|---|" + "---|" * len(cols)]
    aims = []
    for r in bench:
        scene = os.path.basename(r["scene"]).removesuffix(".json")
        mode = r["mode"] + (f" ({r['setting']})" if r.get("setting") else "")
        truth = r.get("truth") == "itself"
        shown = [fmt(r.get(c, "")) if not (truth and c == "in_motion_psnr_min") else "–" for c, _, _ in cols]
        lines.append(f"| {scene} | {mode}{' (truth)' if truth else ''} | " + " | ".join(shown) + " |")
        for c, _, unit in cols:
            rows.append(("bench", scene, f"{mode} {c}", r.get(c, ""), unit))
        if r["mode"].startswith("hybrid") and scene in ("tank_army", "rts_pan"):
            try:
                x = float(r["in_motion_speedup_vs_all_near_vulkan"])
                aims.append(f"- {scene}, {mode}: {x:.2f}× all-near Vulkan in motion "
                            f"({fmt(r['in_motion_ms'])} vs {fmt(r['in_motion_all_near_vulkan_ms'])} ms): "
                            f"{'met' if x >= 5 else 'not met'}")
            except (KeyError, ValueError):
                pass
    if aims:
        lines += ["", "Aim (issue 26): the hybrid at least 5× all-near Vulkan at 1 vpx in motion on the "
                  "tank army and the RTS pan.", ""] + aims
    lines += ["", "The bench's own report, with every column: `bench/report.md`; every figure: `bench/results.csv`."]
else:
    lines.append("The bench wrote no results (see logs/bench.log).")
# The profile: where each frame's time goes, per pass, from the bench's figures (medians of the
# timed frames: the host's parts, then the device's named passes).
if os.environ.get("GC_PROFILE") == "1":
    parts = [("frame_ms", "frame"), ("host_setup_ms", "set-up"), ("host_select_ms", "select"),
             ("host_record_ms", "record"), ("host_record_sprites_ms", "of which sprite records"),
             ("host_record_lists_ms", "of which lists"),
             ("host_record_lists_build_ms", "of which lists' arithmetic"),
             ("host_record_lists_upload_ms", "of which lists' uploads"),
             ("host_record_order_ms", "of which draw order"),
             ("host_record_residency_ms", "of which residency"), ("host_record_far_ms", "of which far pass"),
             ("host_wait_ms", "wait"), ("host_readback_ms", "readback"),
             ("far_ms", "far tier"), ("far_lookup_bake_ms", "of which lookups and bakes"),
             ("far_blit_ms", "of which blit or far pass"),
             ("gpu_frame_ms", "GPU frame"), ("gpu_upload_ms", "GPU upload"), ("gpu_cells_ms", "GPU cells"),
             ("gpu_splat_ms", "GPU splat"), ("gpu_draw_ms", "GPU trace or draw"), ("gpu_resolve_ms", "GPU resolve"),
             ("gpu_far_ms", "GPU far"), ("gpu_copy_ms", "GPU copies")]
    sources = [(os.path.join(out, "bench", "results.csv"), "modes"),
               (os.path.join(out, "tank_curve", "results.csv"), "scaling_entities")]
    profile_rows = []
    for path, group in sources:
        if not os.path.exists(path):
            continue
        with open(path) as f:
            for r in csv.DictReader(f):
                if r.get("group") != group:
                    continue
                scene = os.path.basename(r["scene"]).removesuffix(".json")
                if group == "scaling_entities":
                    scene += f" ({float(r.get('param', 0) or 0):,.0f} entities)"
                profile_rows.append((scene, r["mode"], [], [r.get(c, "") for c, _ in parts]))
    def part_table(heading, intro, table_rows, group, lead=()):
        """A table of `parts` per (scene, mode, lead values, part values); each part value also a
        results.csv row GROUP, scene, "mode column". False where there are no rows."""
        lines.extend(["", heading, "", intro, ""])
        if not table_rows:
            return False
        lines.extend(["| scene | mode | " + " | ".join(list(lead) + [n for _, n in parts]) + " |",
                      "|---|---|" + "---|" * (len(lead) + len(parts))])
        for scene, mode, lead_values, values in table_rows:
            lines.append(f"| {scene} | {mode} | " +
                         " | ".join(fmt(v) for v in list(lead_values) + list(values)) + " |")
            for (c, _), v in zip(parts, values):
                rows.append((group, scene, f"{mode} {c}", v, "ms"))
        return True
    if not part_table("## Where the time goes, pass by pass (ms, medians)",
                      "Host: set-up, selection, recording the Vulkan frame (uploads written), waiting "
                      "on its fence, unpacking the readback. Device: the frame's named timestamps (0 "
                      "where the frame had no such pass). `bench/results.csv`, "
                      "`tank_curve/results.csv`.", profile_rows, "profile"):
        lines.append("No profile rows: see logs/bench.log and logs/tank_curve.log.")
    # The same parts for the bench's frames in motion: each part's mean per frame over the frames
    # timed in motion (the in_motion_mean_* columns), which add up to the mean frame in motion,
    # bakes and view changes included; the warm frame above has every snapshot it needs.
    motion_rows = []
    if os.path.exists(bench_csv):
        with open(bench_csv) as f:
            for r in csv.DictReader(f):
                if r.get("group") != "modes" or not float(r.get("in_motion_ms") or 0):
                    continue
                scene = os.path.basename(r["scene"]).removesuffix(".json")
                motion_rows.append((scene, r["mode"], [r.get("in_motion_ms", "")],
                                    [r.get("in_motion_mean_" + c, "") for c, _ in parts]))
    if not part_table("## Where the time goes in motion, pass by pass (ms per frame, means)",
                      "The bench's frames timed in motion, each part's mean per frame "
                      "(`in_motion_mean_*` in `bench/results.csv`): they add up to the mean frame in "
                      "motion (the *frame* column), its bakes, view changes and selection included; "
                      "*median* is the in-motion figure the speed-ups use.", motion_rows,
                      "profile_in_motion", lead=("median",)):
        lines.append("No in-motion rows: see logs/bench.log.")
    # Frames in flight: the median frame of frames 6-47 of `render --frames 0:47` (the first six
    # are the cold start, as in the bench), beside the bench's figure, which draws one frame at a
    # time. A frame's time is its host part plus the wait and readback of its finish.
    flight = []
    for s in ("street", "tank_army", "rts_pan"):
        path = os.path.join(out, "in_flight", s + ".csv")
        if not os.path.exists(path):
            continue
        with open(path) as f:
            frames = list(csv.DictReader(f))[6:]
        if not frames:
            continue
        frame_ms, wait_ms, gpu_ms = (middle([float(r[c]) for r in frames])
                                     for c in ("frame_ms", "host_wait_ms", "gpu_frame_ms"))
        serial = next((r.get("in_motion_ms", "") for r in (bench if os.path.exists(bench_csv) else [])
                       if os.path.basename(r["scene"]).removesuffix(".json") == s and r["mode"] == "near_vulkan"), "")
        flight.append((s, len(frames), frame_ms, wait_ms, gpu_ms, serial))
        rows.append(("in_flight", s, "near_vulkan frame_ms", frame_ms, "ms"))
        rows.append(("in_flight", s, "near_vulkan gpu_frame_ms", gpu_ms, "ms"))
    lines += ["", "## All-near Vulkan in motion with frames in flight (ms, medians)", "",
              "`voxtier render scenes/bench/S.json --mode near --near-backend vulkan --frames 0:47 --csv`: "
              "frame k+1 is set up, recorded and on the device while frame k is read back. Frames 6-47; "
              "the bench's in-motion figure draws one frame at a time.", ""]
    if flight:
        lines += ["| scene | frames | frame in flight | host wait | GPU frame | bench, one at a time |",
                  "|---|---|---|---|---|---|"]
        for s, n, fr, wait, gpu, serial in flight:
            lines.append(f"| {s} | {n} | {fmt(fr)} | {fmt(wait)} | {fmt(gpu)} | {fmt(serial)} |")
    else:
        lines.append("No in-flight rows: see logs/in_flight.log.")
    # The far pass's tiles, then direct writes against staged uploads: medians of frames 6-23 of
    # each render of the curve's largest army.
    big = os.environ.get("GC_BIG") or "0"
    def army_medians(name, cols):
        """(frames, medians of `cols`) of far_tiles/NAME.csv past its first six frames, or None."""
        path = os.path.join(out, "far_tiles", name + ".csv")
        if not os.path.exists(path):
            return None
        with open(path) as f:
            frames = list(csv.DictReader(f))[6:]
        if not frames:
            return None
        return len(frames), [middle([float(r.get(c) or 0) for r in frames]) for c in cols]
    def army_table(group, renders, cols):
        """Per (label, NAME, item) of `renders` with a far_tiles/NAME.csv: (label, frames, medians),
        each medians' _ms column also a results.csv row GROUP, tank_army_BIG, "item column"."""
        table = []
        for label, name, item in renders:
            got = army_medians(name, cols)
            if not got:
                continue
            table.append((label, *got))
            for c, v in zip(cols, got[1]):
                if c.endswith("_ms"):
                    rows.append((group, f"tank_army_{big}", f"{item} {c}", v, "ms"))
        return table
    def last_frames(result):
        """What same_last_frame wrote into far_tiles/RESULT."""
        path = os.path.join(out, "far_tiles", result)
        return open(path).read().strip() if os.path.exists(path) else "not compared"
    # The whole hybrid frame's host side too (run 11 put the far tier's share, lookups, bakes and
    # recording with its device time, at 8-10 ms of a 19-23 ms frame, and said no more).
    tiles_cols = ("frame_ms", "host_setup_ms", "host_select_ms", "far_ms", "far_lookup_bake_ms",
                  "far_bakes", "host_record_ms", "host_record_sprites_ms", "host_record_lists_ms",
                  "host_record_order_ms", "host_record_residency_ms", "host_record_far_ms",
                  "gpu_frame_ms", "gpu_far_ms", "far_entities")
    renders = (("hybrid, coarse", "coarse", "hybrid_gpu_far coarse"),
               ("hybrid, fine", "fine", "hybrid_gpu_far fine"),
               ("hybrid, sprites", "sprites", "hybrid_gpu_far sprites"),
               ("all far, coarse", "far_coarse", "far coarse"),
               ("all far, fine", "far_fine", "far fine"),
               ("all far, sprites", "far_sprites", "far sprites"),
               ("all far, still camera", "far_still", "far still"))
    tiles_rows = army_table("far_tiles", renders, tiles_cols)
    same, same_far = last_frames("identity.txt"), last_frames("far_identity.txt")
    by_sprite, by_sprite_far = last_frames("sprites_identity.txt"), last_frames("far_sprites_identity.txt")
    lines += ["", f"## The far pass: {int(big):,} tanks, hybrid and all far, its tiles, in flight (ms, medians)", "",
              f"`voxtier render tank_army_{big}.json --mode hybrid|far --far-backend vulkan --far-tiles T --frames 0:23 --csv`, "
              "and all far under a still camera (the path removed, the device's default cut): "
              f"frames 6-23. Frame 23, coarse against fine: {same}; coarse against sprites: {by_sprite}; "
              f"all far, coarse against fine: {same_far}; all far, coarse against sprites: {by_sprite_far}. "
              "The far tier's share (`far_ms`) is its snapshot lookups and bakes (`far_lookup_bake_ms`, "
              "`far_bakes` of them), its recording (within `host_record_ms`, beside the near tier's sprite "
              "records and lists) and its device time.", ""]
    if tiles_rows:
        lines += ["| render | frames | frame in flight | set-up | select | far tier | of which lookups and bakes "
                  "| bakes | host record | of which near sprite records | of which near lists "
                  "| of which near draw order | of which residency | of which far pass | GPU frame "
                  "| GPU far pass | far entities |", "|---" * 17 + "|"]
        for label, n, v in tiles_rows:
            lines.append(f"| {label} | {n} | " + " | ".join(fmt(x) for x in v) + " |")
    else:
        lines.append("No far-tiles rows: see logs/far_tiles.log.")
    cols = ("frame_ms", "host_record_ms", "host_record_sprites_ms", "host_record_lists_ms",
            "host_record_lists_build_ms", "host_record_lists_upload_ms",
            "host_record_order_ms", "host_record_residency_ms", "gpu_upload_ms", "gpu_frame_ms")
    def near_pair_table(group, ways, name, item, heading, text, first, log):
        """The all-near army rendered two ways (far_tiles/NAME(way).csv): its recording's parts
        per way under HEADING and TEXT, the first column FIRST, or where to look (LOG)."""
        table = army_table(group, [(w, name(w), item(w)) for w in ways], cols)
        lines.extend(["", f"## {heading}: {int(big):,} tanks, all-near Vulkan, in flight (ms, medians)", "", text, ""])
        if not table:
            lines.append(f"No {group} rows: see {log}.")
            return
        lines.extend([f"| {first} | frames | frame in flight | host record | of which sprite records | of which lists "
                      "| of which lists' arithmetic | of which lists' uploads "
                      "| of which draw order | of which residency | GPU upload | GPU frame |", "|---" * 12 + "|"])
        for way, n, v in table:
            lines.append(f"| {way} | {n} | " + " | ".join(fmt(x) for x in v) + " |")
    near_pair_table("placement", ("direct", "staged"), lambda p: f"near_{p}", lambda p: f"near_vulkan {p}",
                    "Direct writes or staged uploads",
                    f"`voxtier render tank_army_{big}.json --mode near --near-backend vulkan --frames 0:23 --csv`, "
                    "as the memory policy places the buffers (direct: written through the BAR where the device offers "
                    f"it) and with `VOXTIER_FORCE_STAGING=1`; frames 6-23. Frame 23, direct against staged: "
                    f"{last_frames('placement_identity.txt')}.", "uploads", "logs/placement.log")
    near_pair_table("records", ("drawn", "given"), lambda l: f"records_{l}", lambda l: f"near_vulkan records {l}",
                    "Sprite records in the draw order or in entity order",
                    f"`voxtier render tank_army_{big}.json --mode near --near-backend vulkan --near-records drawn|given "
                    f"--frames 0:23 --csv`; frames 6-23. Frame 23, drawn against given: {last_frames('records_identity.txt')}. "
                    "The records are what `of which sprite records` holds beside the draw order and the residency.",
                    "records", "logs/records.log")
    # The error budget's hybrid against all-near Vulkan (the direct-write render above), the
    # same army and frames: issue 35's aim at 100,000 is <= 10 ms and >= 3x all-near.
    # The selection's parts too: runs 12 and 13 put it at 16-36 ms on 16 cores, about what two
    # cores take, and the total could not say which step does not shrink with the cores.
    budget_cols = ("frame_ms", "host_setup_ms", "host_select_ms", "host_select_inputs_ms",
                   "host_select_tiers_ms", "host_select_views_ms", "host_select_choices_ms",
                   "host_select_cost_bound_ms", "host_select_predictions_ms", "cache_questions",
                   "far_ms", "far_bakes",
                   "host_record_ms", "gpu_frame_ms", "gpu_far_ms", "far_entities")
    budget_rows = army_table("error_budget", (("hybrid, error budget 1 vpx", "budget", "hybrid_budget"),
                                              ("all near", "near_direct", "near_vulkan")), budget_cols)
    lines += ["", f"## The error budget: {int(big):,} tanks, hybrid against all-near Vulkan, in flight (ms, medians)", "",
              f"`voxtier render tank_army_{big}_budget.json --mode hybrid --far-backend vulkan --frames 0:23 --csv` "
              "(the army with `\"selector\": {\"metric\": \"error_budget\", \"budget_vpx\": 1}`: most tanks far, "
              "each within 1 vpx by prediction) beside the all-near render above; frames 6-23, the snapshot cache "
              "filling as the camera moves.", ""]
    if budget_rows:
        lines += ["| render | frames | frame in flight | set-up | select | of which inputs | of which tiers "
                  "| of which views | of which choices | of which cost bound | of which predictions "
                  "| cache questions | far tier | bakes | host record | GPU frame | GPU far pass "
                  "| far entities |",
                  "|---" * 18 + "|"]
        for label, n, v in budget_rows:
            lines.append(f"| {label} | {n} | " + " | ".join(fmt(x) for x in v) + " |")
        if len(budget_rows) == 2:
            hybrid_ms, near_ms = budget_rows[0][2][0], budget_rows[1][2][0]
            x = near_ms / hybrid_ms if hybrid_ms > 0 else 0.0
            rows.append(("error_budget", f"tank_army_{big}", "hybrid_budget speedup_vs_all_near_vulkan", f"{x:.3g}", "x"))
            met = hybrid_ms <= 10 and x >= 3
            lines += ["", f"Aim (issue 35, at 100,000 tanks; this army has {int(big):,}): the hybrid <= 10 ms "
                      f"and >= 3x all-near Vulkan: {fmt(hybrid_ms)} ms, {x:.2f}x: {'met' if met else 'not met'}."]
    else:
        lines.append("No error-budget rows: see logs/far_tiles.log.")
# The GPU's SM clock in each phase (nvidia-smi every 100 ms; logs/clocks.csv), in every run:
# it explains the bench's Vulkan figures with or without --profile.
clocks_csv, phases_txt = os.path.join(out, "logs", "clocks.csv"), os.path.join(out, "logs", "phases.txt")
if os.path.exists(clocks_csv) and os.path.exists(phases_txt):
    samples = []
    for line in open(clocks_csv):
        parts = [p.strip() for p in line.split(",")]
        try:
            t = datetime.datetime.strptime(parts[0], "%Y/%m/%d %H:%M:%S.%f").timestamp()
            samples.append((t, float(parts[1]), float(parts[2])))
        except (ValueError, IndexError):
            pass
    marks = [(float(a), b.strip()) for a, b in (l.split(None, 1) for l in open(phases_txt) if l.strip())]
    table = []
    for (a, name), (b, _) in zip(marks, marks[1:]):
        seg = [x[1] for x in samples if a <= x[0] < b]
        if seg:
            table.append((name, b - a, middle(seg), min(seg), max(seg), len(seg)))
            rows.append(("clocks", name, "sm_clock_median", middle(seg), "MHz"))
    if table:
        lines += ["", "## The GPU's SM clock by phase (nvidia-smi, every 100 ms)", "",
                  "A GPU that idles between frames runs the next one at a low clock: the bench "
                  "draws the CPU modes between its Vulkan frames, the in-flight renders keep the "
                  "GPU busy.", "",
                  "| phase | s | median MHz | min | max | samples |", "|---|---|---|---|---|---|"]
        for name, secs, med, lo, hi, n in table:
            lines.append(f"| {name} | {secs:.1f} | {med:.0f} | {lo:.0f} | {hi:.0f} | {n} |")
with open(os.path.join(out, "report.md"), "w") as f:
    f.write("\n".join(lines) + "\n")
with open(os.path.join(out, "results.csv"), "w", newline="") as f:
    w = csv.writer(f)
    w.writerow(("section", "scene", "item", "value", "unit"))
    w.writerows(rows)
PY
else
    # No python3: the same facts, less tabulated.
    {
        echo "# voxtier GPU check"
        echo
        echo "- Binary: $version"
        echo "- Vulkan device: **$device**"
        echo "- ${total_s} s in all, the bench ${bench_s} s; $([[ $failed == 1 ]] && echo FAILED || echo 'every identity check passed')"
        echo
        echo "Identity (Vulkan near vs CPU reference): identity_near.csv. Bench: bench/report.md."
    } >"$out/report.md"
    {
        echo "section,scene,item,value,unit"
        echo "run,,device,\"$device\","
        tail -n +2 "$out/identity_near.csv" | awk -F, '{print "identity_near," $1 ",colour/depth/id diffs," $8 "/" $9 "/" $10 ",pixels"}'
    } >"$out/results.csv"
fi
echo "gpu_check: ${total_s} s; wrote $out/report.md and $out/results.csv"
((failed == 0)) || {
    echo "gpu_check: FAILED (see $out/report.md)" >&2
    exit 1
}
