// `voxtier bench`'s report (apps/bench/report.hpp): report.md filled into
// apps/bench/report.md.mustache (embedded in the binary at build time, apps/CMakeLists.txt),
// every number formatted here.
#include "apps/bench/report.hpp"

#include "apps/bench/plots.hpp"
#include "apps/bench/report_cells.hpp"
#include "apps/bench/time_split.hpp"
#include "core/file_write.hpp"
#include "embedded/bench_report_template.h"
#include "impostor_cache/far_blit.hpp"

#include <kainjow/mustache.hpp>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <map>
#include <regex>
#include <set>

namespace voxtier::bench {

namespace {

using nlohmann::json;
using namespace cells;

bool isErrorSelector(const Measurement& m) {
    return m.selector.rfind("error_px", 0) == 0;
}

// ---------------------------------------------------------------------------------------------
// The goal of the hybrid frame (10x the fastest exact path within the error budget): the goal
// table's ✓/✗ and the choice of the best error-selector setting "within the error budget" both
// read it.

struct Goals {
    double minSpeedup = 10.0;      ///< against the fastest exact path
    double maxMeanMismatch = 0.02; ///< mean footprint mismatch
    /// Far entities displaced by more than one virtual pixel (drawn alone), per frame.
    double maxFarOverOneCell = 0.0;
};
constexpr Goals kGoals;

bool fastEnough(const Measurement& m) {
    return m.speedupVsFastestExact >= kGoals.minSpeedup;
}
bool closeEnough(const Measurement& m) {
    return m.error.mismatchMean <= kGoals.maxMeanMismatch;
}
bool steadyEnough(const Measurement& m) {
    return m.error.farDisplacedOver1Vpx <= kGoals.maxFarOverOneCell;
}
std::string verdict(bool met) {
    return met ? " ✓" : " ✗";
}
// ---------------------------------------------------------------------------------------------
// report.md: the template's context, every number formatted here.

std::string entitiesCell(const Measurement& m) {
    std::string s =
        num(perFrame(m, "near_entities"), 0) + " / " + num(perFrame(m, "far_entities"), 0);
    const double fading = perFrame(m, "fading_entities");
    if (fading >= 0.5) s += " (" + num(fading, 0) + " fading)";
    return s;
}

/// Far entities displaced by more than one virtual pixel, of those drawn alone, per frame.
std::string overOne(const Measurement& m) {
    return m.error.farAloneEntities > 0
               ? count(m.error.farDisplacedOver1Vpx) + " of " + count(m.error.farAloneEntities)
               : "–";
}

std::string speedupCell(const Measurement& m) {
    return m.speedupVsAllNearVulkan > 0 ? num(m.speedupVsAllNearVulkan, 1) + "×" : "–";
}

/// The near fragments a frame still draws over those of the all-near frame drawn the same way
/// (Measurement::allNearSameBackendFragments). It can pass 100 %: far sprites take no part in
/// the near tier's early depth test, so near pixels behind them are traced where all-near
/// skipped them.
std::string nearShareCell(const Measurement& m) {
    if (m.allNearSameBackendFragments <= 0) return "–";
    const double share = perFrame(m, "near_fragments") / m.allNearSameBackendFragments;
    return pct(share, 1) + (share > 1.0 ? " (near pixels behind far sprites traced)" : "");
}

/// The in-motion cells of a row (issue 13): median / 90th-percentile frame ms after the cold
/// start (cold start), speed-up, bakes per frame, min PSNR and differing pixels against all-near
/// in motion.
json motionCells(const Measurement& m) {
    if (m.motion.ms <= 0)
        return {{"motion_ms", "–"},
                {"motion_speedup", "–"},
                {"motion_bakes", "–"},
                {"motion_error", "–"}};
    return {{"motion_ms",
             num(m.motion.ms) + " / " + num(m.motion.p90Ms) + " (" + num(m.motion.coldMs) + ")"},
            {"motion_speedup", m.motion.speedupVsAllNearVulkan > 0
                                   ? num(m.motion.speedupVsAllNearVulkan, 1) + "×"
                                   : "–"},
            {"motion_bakes", num(m.motion.bakes, 1) + " / " + num(m.motion.bakeMs, 1) + " ms"},
            {"motion_error", m.motion.psnrMin > 0 ? num(m.motion.psnrMin, 1) + " dB, " +
                                                        pct(m.motion.differingShare) + " px"
                                                  : "(truth)"}};
}

/// The error cells of a row, or false for the truth.
json errorCells(const Measurement& m) {
    if (!m.hasError) return false;
    return {
        {"mismatch", pct(m.error.mismatchMean) + " (" + pct(m.error.coverageMismatchMean) + ")"},
        {"worst", pct(m.error.mismatchWorst)},
        {"displacement", num(m.error.farDisplacementWorstPx, 1) + " px (" +
                             num(m.error.farDisplacementWorstVpx, 2) + ")"},
        {"over_one", overOne(m)},
        {"rmse", num(m.error.rmseMean, 4)},
        {"psnr", num(m.error.psnrMin, 1)}};
}

std::string settingOf(const Measurement& m) {
    return m.mode == BenchMode::Far ? "all far" : m.setting.empty() ? m.selector : m.setting;
}

/// One column of the goal table; `missing` (why there is no such setting) in place of one.
json goalColumn(const Measurement* m, const std::string& missing) {
    if (!m)
        return {{"setting", missing},
                {"speedup", "–"},
                {"mismatch", "–"},
                {"displacement", "–"},
                {"near_share", "–"}};
    return {{"setting", settingOf(*m)},
            {"speedup", (m->speedupVsFastestExact > 0 ? num(m->speedupVsFastestExact, 1) + "×"
                                                      : std::string("–")) +
                            verdict(fastEnough(*m))},
            {"mismatch", pct(m->error.mismatchMean) + " (" + pct(m->error.coverageMismatchMean) +
                             ")" + verdict(closeEnough(*m))},
            {"displacement", "worst " + num(m->error.farDisplacementWorstVpx, 2) + "; " +
                                 overOne(*m) + " per frame" + verdict(steadyEnough(*m))},
            {"near_share", nearShareCell(*m)}};
}

/// The first scene's hybrid against the fastest exact path (warm re-render), and the goal
/// table: the hybrid as configured, the fastest error-selector setting within the error budget,
/// the fastest measured setting.
json headlineContext(const SuiteResults& r, const std::string& scene) {
    const Measurement* hyb = find(r, kModesGroup, scene, BenchMode::Hybrid);
    if (!hyb || hyb->fastestExactMs <= 0) return false;
    const Measurement* best = nullptr;
    const Measurement* fastest = nullptr;
    int errorSettings = 0;
    for (const Measurement& m : r.rows) {
        const RenderMode mode = info(m.mode).renderMode;
        if (m.scene != scene || (m.group != kModesGroup && m.group != "sweep") || !m.hasError ||
            (mode != RenderMode::Hybrid && mode != RenderMode::Far) || m.fastestExactMs <= 0)
            continue;
        const bool errorSetting = m.mode == BenchMode::Hybrid && isErrorSelector(m);
        errorSettings += errorSetting;
        if (errorSetting && closeEnough(m) && steadyEnough(m) &&
            (!best || m.speedupVsFastestExact > best->speedupVsFastestExact))
            best = &m;
        if (!fastest || m.speedupVsFastestExact > fastest->speedupVsFastestExact) fastest = &m;
    }
    const std::string noBest = errorSettings == 0
                                   ? "none: no error_px setting measured"
                                   : "none within the budget (" + std::to_string(errorSettings) +
                                         " error_px setting" + (errorSettings == 1 ? "" : "s") +
                                         " measured)";
    return {{"scene", scene},
            {"selector", hyb->selector},
            {"hybrid_ms", num(hyb->frameMs())},
            {"fastest", hyb->fastestExact},
            {"fastest_ms", num(hyb->fastestExactMs)},
            {"speedup", num(hyb->speedupVsFastestExact, 2) + "×"},
            {"vs_vulkan", speedupCell(*hyb)},
            {"near_entities", num(perFrame(*hyb, "near_entities"), 0)},
            {"far_entities", num(perFrame(*hyb, "far_entities"), 0)},
            {"mismatch_mean", pct(hyb->error.mismatchMean)},
            {"mismatch_worst", pct(hyb->error.mismatchWorst)},
            {"displacement_px", num(hyb->error.farDisplacementWorstPx, 1)},
            {"displacement_vpx", num(hyb->error.farDisplacementWorstVpx, 2)},
            {"goals",
             {{"speedup", num(kGoals.minSpeedup, 0) + "×"},
              {"mismatch", pct(kGoals.maxMeanMismatch, 0)}}},
            {"goal_columns",
             {goalColumn(hyb, "–"), goalColumn(best, noBest), goalColumn(fastest, "–")}}};
}

/// How an exact mode draws: its near backend and the near rate it ran at.
std::string exactPathWords(const std::string& mode, NearRate rate) {
    const std::string backend =
        mode == toString(BenchMode::NearReference) ? "the CPU reference tracer" : "Vulkan";
    return backend + (rate == NearRate::Auto   ? ", cell-rate where cheaper"
                      : rate == NearRate::Cell ? ", cell-rate"
                                               : ", per pixel");
}

} // namespace

std::vector<std::string> leadLines(const SuiteResults& r, bool markdown) {
    const std::string bold = markdown ? "**" : "";
    std::vector<std::string> lines;
    for (const std::string& scene : sceneNames(r)) {
        const Measurement* h = find(r, kModesGroup, scene, BenchMode::Hybrid);
        if (!h) continue;
        // In motion where the scene has a camera path (what a game sees: bakes included), else
        // the warm re-render of its one frame.
        const bool moving = h->motion.ms > 0 && h->motion.fastestExactMs > 0;
        const double ms = moving ? h->motion.ms : h->frameMs();
        const double fastestMs = moving ? h->motion.fastestExactMs : h->fastestExactMs;
        const std::string fastest = !moving ? h->fastestExact
                                    : h->motion.fastestExactMs == h->motion.allNearReferenceMs
                                        ? toString(BenchMode::NearReference)
                                        : toString(BenchMode::NearVulkan);
        std::string line = bold + scene + bold + ": ";
        if (fastestMs <= 0) {
            lines.push_back(line + "no exact path was measured to set the hybrid against.");
            continue;
        }
        const double psnr = moving ? h->motion.psnrMin : h->error.psnrMin;
        const double differing =
            moving ? h->motion.differingShare
                   : (h->imagePixels > 0 ? h->error.differingPixels / h->imagePixels : 0.0);
        line += "the hybrid is " + bold + num(fastestMs / ms, 2) + "×" + bold +
                " the fastest exact path on this machine: " + num(ms) + " ms a frame " +
                (moving ? "in motion" : "(warm re-render; the scene has no camera path)") +
                " against " + num(fastestMs) + " ms for " + fastest + " (" +
                exactPathWords(fastest, r.plan.frame.nearRate) +
                "); error against all-near: min frame PSNR " + psnrText(psnr) + ", " +
                pct(differing) + " of pixels differing" + (moving ? " (mean)" : "") + ", " +
                (h->error.farAloneEntities > 0
                     ? "worst far displacement " + num(h->error.farDisplacementWorstVpx, 2) + " vpx"
                     : "no far sprite on the sampled frames to displace") +
                ".";
        lines.push_back(line);
    }
    return lines;
}

namespace {

/// Per scene, the hybrid in motion against both exact paths (issue 24): all-near on the CPU
/// reference and on Vulkan, which of them is faster on this machine, and the error the speed-up
/// costs, beside the far blit's throughput.
json baselinesContext(const SuiteResults& r) {
    json rows = json::array();
    for (const std::string& scene : sceneNames(r)) {
        const Measurement* h = find(r, kModesGroup, scene, BenchMode::Hybrid);
        const Measurement* ref = find(r, kModesGroup, scene, BenchMode::NearReference);
        const Measurement* vk = find(r, kModesGroup, scene, BenchMode::NearVulkan);
        if (!h || !ref || !vk || h->motion.ms <= 0) continue;
        const bool referenceFaster = ref->motion.ms > 0 && ref->motion.ms < vk->motion.ms;
        const double fastestMs = referenceFaster ? ref->motion.ms : vk->motion.ms;
        rows.push_back(
            {{"scene", scene},
             {"hybrid_ms", num(h->motion.ms)},
             {"near_backend", h->nearBackend},
             {"reference_ms", num(ref->motion.ms)},
             {"vs_reference", h->motion.speedupVsAllNearReference > 0
                                  ? num(h->motion.speedupVsAllNearReference, 1) + "×"
                                  : "–"},
             {"vulkan_ms", num(vk->motion.ms)},
             {"vs_vulkan", h->motion.speedupVsAllNearVulkan > 0
                               ? num(h->motion.speedupVsAllNearVulkan, 1) + "×"
                               : "–"},
             {"fastest", referenceFaster ? "near_reference" : "near_vulkan"},
             {"vs_fastest", num(fastestMs / h->motion.ms, 1) + "×"},
             {"error", h->motion.psnrMin > 0 ? num(h->motion.psnrMin, 1) + " dB, " +
                                                   pct(h->motion.differingShare) + " px"
                                             : "–"},
             {"displacement", h->hasError ? num(h->error.farDisplacementWorstVpx, 2) : "–"},
             {"blit",
              h->blitPixelsPerS > 0
                  ? mega(h->blitPixelsPerS) + " M (" +
                        (h->memcpyPixelsPerS > 0 ? pct(h->blitPixelsPerS / h->memcpyPixelsPerS, 1)
                                                 : std::string("–")) +
                        ")"
                  : "–"}});
    }
    return rows;
}

json modesContext(const SuiteResults& r) {
    json scenes = json::array();
    for (const std::string& scene : sceneNames(r)) {
        json modes = json::array();
        for (const BenchModeInfo& mode : kBenchModes)
            if (const Measurement* m = find(r, kModesGroup, scene, mode.mode)) {
                modes.push_back(
                    {{"mode", mode.name},
                     {"entities", entitiesCell(*m)},
                     {"frame_ms", num(m->frameMs())},
                     // Only a frame drawn wholly on Vulkan can skip its readback.
                     {"device_frame_ms",
                      m->deviceFrameMs > 0 ? num(m->deviceFrameMs) : "– (a CPU tier)"},
                     {"worst_frame_ms", num(m->worstFrameMs)},
                     {"speedup", speedupCell(*m)},
                     {"speedup_vs_fragment", m->speedupVsNearVulkanFragment > 0
                                                 ? num(m->speedupVsNearVulkanFragment, 1) + "×"
                                                 : "–"},
                     {"error", errorCells(*m)}});
                modes.back().update(motionCells(*m));
            }
        const Measurement* ref = find(r, kModesGroup, scene, BenchMode::NearReference);
        scenes.push_back({{"scene", scene},
                          {"modes", modes},
                          {"reference_differing",
                           ref ? json(num(ref->error.differingPixels, 0)) : json(false)}});
    }
    return scenes;
}

/// Issue 13's target for the error budget, in motion: at 1 virtual pixel, at least 3x the
/// per-pixel near tier with every far entity within the budget and PSNR >= 40 dB.
struct BudgetTarget {
    double budgetVpx = 1.0;
    double minSpeedupVsFragment = 3.0;
    double minPsnrDb = 40.0;
};
constexpr BudgetTarget kBudgetTarget;

/// The displacement measured on the sampled frames beside the prediction, and why it can be
/// larger: the budget bounds the continuous footprints, and both tiers point-sample whole cells,
/// so a silhouette moved by less than a cell still flips cells, a diagonal flip measuring √2
/// (CONTRACT.md §5; tests/error_budget_test.cpp checks measured ≤ predicted + that allowance).
std::string measuredDisplacement(const Measurement& m) {
    if (!m.hasError || m.error.farAloneEntities <= 0) return "";
    std::string s = " (measured worst " + num(m.error.farDisplacementWorstVpx, 2) +
                    " vpx on the sampled frames";
    if (m.error.farDisplacedOver1Vpx > 0)
        s += ", " + num(m.error.farDisplacedOver1Vpx, 1) + " of " +
             num(m.error.farAloneEntities, 1) +
             " far entities a frame over 1: both tiers point-sample whole cells, so an outline "
             "moved by less than a cell still flips cells, and a diagonal flip measures √2";
    return s + ")";
}

/// What a PSNR target asks of the budget's worst frame: the squared error is the differing
/// share times the mean squared error of a differing pixel, so at the same error per differing
/// pixel the target allows only share / 10^((target - PSNR) / 10) of the pixels to differ. Far
/// sprites differ from near ones wherever their outline cells move, which any view but an exact
/// one does (CONTRACT.md §5), so the allowance per far sprite says whether the target is in reach.
std::string psnrBound(const Measurement& m) {
    const double psnr = m.motion.psnrMin;
    if (!std::isfinite(psnr) || psnr >= kBudgetTarget.minPsnrDb ||
        m.motion.psnrMinDifferingPixels <= 0)
        return ""; // (no differing pixel: no share either)
    const double factor = std::pow(10.0, (kBudgetTarget.minPsnrDb - psnr) / 10.0);
    const double pixels = m.motion.psnrMinDifferingPixels / factor;
    std::string s = num(kBudgetTarget.minPsnrDb, 0) + " dB asks for a " +
                    num(factor, factor < 10.0 ? 2 : 0) +
                    "× smaller squared error than the worst frame (" + num(psnr, 1) + " dB, " +
                    num(m.motion.psnrMinDifferingPixels, 0) + " pixels differing, " +
                    pct(m.motion.psnrMinShare) + "): at the same error per differing pixel, " +
                    num(pixels, 0) + " differing pixels";
    if (m.motion.psnrMinFarEntities > 0)
        s += ", " + num(pixels / m.motion.psnrMinFarEntities, 1) + " per far sprite (" +
             num(m.motion.psnrMinFarEntities, 0) +
             " far), while a far sprite drawn from any view but an "
             "exact one moves its outline cells";
    return s + ". ";
}

/// The error budget in motion, per scene with budget sweep rows: each budget against the
/// per-pixel near tier, and a verdict that says what stops the target. The ceiling is the
/// per-pixel frame's in-motion mean over the budget frame's near time: the speed-up if far
/// sprites and bakes cost nothing, since the entities drawn near (kept by the budget or by the
/// bake bounds) still cost that.
json budgetTargetContext(const SuiteResults& r) {
    json scenes = json::array();
    for (const std::string& scene : sceneNames(r)) {
        const Measurement* frag = find(r, kModesGroup, scene, BenchMode::NearVulkanFragment);
        if (!frag || frag->motion.ms <= 0) continue;
        // The budget sweep runs each budget with every snapshot scale; the target is read on the
        // plan's first (the frontier section sets them side by side).
        const int first = r.plan.snapshotScales.empty() ? 1 : r.plan.snapshotScales.front();
        std::vector<const Measurement*> budgets;
        for (const Measurement& m : r.rows)
            if (m.scene == scene && m.family == kBudgetFamily && m.motion.ms > 0 &&
                m.snapshotScale == first)
                budgets.push_back(&m);
        if (budgets.empty()) continue;
        std::sort(budgets.begin(), budgets.end(),
                  [](const Measurement* a, const Measurement* b) { return a->param < b->param; });
        const auto ceiling = [&](const Measurement& m) {
            return m.motion.nearMs > 0 ? frag->motion.meanMs / m.motion.nearMs : 0.0;
        };
        json rows = json::array();
        const Measurement* target = nullptr;
        const Measurement* loosest40 = nullptr; // the largest budget that still reached 40 dB
        const Measurement* sharpest = budgets.front();
        for (const Measurement* m : budgets) {
            if (m->param == kBudgetTarget.budgetVpx) target = m;
            if (m->motion.psnrMin >= kBudgetTarget.minPsnrDb) loosest40 = m;
            if (m->motion.psnrMin > sharpest->motion.psnrMin) sharpest = m;
            rows.push_back(
                {{"budget", num(m->param, 2) + " vpx"},
                 {"entities",
                  num(m->motion.nearEntities, 0) + " / " + num(m->motion.farEntities, 0)},
                 {"motion_ms", num(m->motion.ms) + " (" + num(m->motion.meanMs) + ")"},
                 {"vs_fragment", num(frag->motion.ms / m->motion.ms, 2) + "× (" +
                                     num(frag->motion.meanMs / m->motion.meanMs, 2) + "×)"},
                 {"near_ms", num(m->motion.nearMs)},
                 {"bake_ms", num(m->motion.bakeMs)},
                 {"ceiling", num(ceiling(*m), 2) + "×"},
                 {"error", num(m->motion.psnrMin, 1) + " dB, " + pct(m->motion.differingShare)},
                 {"predicted", num(m->motion.predictedWorstVpx, 2)}});
        }
        std::string line = "**" + scene + "**: ";
        if (!target) {
            line += "no row at " + num(kBudgetTarget.budgetVpx, 0) + " vpx was measured.";
        } else {
            const double speedup = frag->motion.ms / target->motion.ms;
            line += "at " + num(kBudgetTarget.budgetVpx, 0) + " vpx, " + num(speedup, 2) +
                    "× the per-pixel frame in motion (median; target ≥ " +
                    num(kBudgetTarget.minSpeedupVsFragment, 0) + "×)" +
                    verdict(speedup >= kBudgetTarget.minSpeedupVsFragment) + ", PSNR min " +
                    num(target->motion.psnrMin, 1) + " dB (target ≥ " +
                    num(kBudgetTarget.minPsnrDb, 0) + ")" +
                    verdict(target->motion.psnrMin >= kBudgetTarget.minPsnrDb) +
                    ", predicted worst " + num(target->motion.predictedWorstVpx, 2) + " vpx" +
                    verdict(target->motion.predictedWorstVpx <= kBudgetTarget.budgetVpx) +
                    measuredDisplacement(*target) + ". The near tier alone takes " +
                    num(target->motion.nearMs) + " ms a frame for " +
                    num(target->motion.nearEntities, 0) +
                    " near entities, so free far sprites and free bakes would give at most " +
                    num(ceiling(*target), 2) + "× (means). " + psnrBound(*target);
        }
        line += loosest40
                    ? "PSNR ≥ " + num(kBudgetTarget.minPsnrDb, 0) + " dB up to " +
                          num(loosest40->param, 2) + " vpx, where the frame is " +
                          num(frag->motion.ms / loosest40->motion.ms, 2) + "× per pixel (ceiling " +
                          num(ceiling(*loosest40), 2) + "×)."
                    : "PSNR ≥ " + num(kBudgetTarget.minPsnrDb, 0) +
                          " dB at no budget measured (best " + num(sharpest->motion.psnrMin, 1) +
                          " dB, at " + num(sharpest->param, 2) + " vpx).";
        scenes.push_back({{"scene", scene}, {"rows", rows}, {"verdict", line}});
    }
    if (scenes.empty()) return false;
    return {{"scenes", scenes},
            {"budget", num(kBudgetTarget.budgetVpx, 0)},
            {"speedup", num(kBudgetTarget.minSpeedupVsFragment, 0)},
            {"psnr", num(kBudgetTarget.minPsnrDb, 0)}};
}

/// The speed–error frontier of every scene with budget sweep points in motion (the first scene):
/// each snapshot scale's points by budget, the Pareto frontier marked.
json frontierContext(const SuiteResults& r, bool plotted) {
    json scenes = json::array();
    for (const std::string& scene : sceneNames(r)) {
        const std::vector<FrontierCurve> curves = frontierCurves(r, scene);
        const Measurement* ref = find(r, kModesGroup, scene, BenchMode::NearReference);
        const Measurement* vk = find(r, kModesGroup, scene, BenchMode::NearVulkan);
        if (curves.empty() || !ref || !vk) continue;
        const std::set<const Measurement*> front = frontierPareto(curves);
        json rows = json::array();
        for (const FrontierCurve& c : curves)
            for (const Measurement* m : c.points)
                rows.push_back({{"variant", c.variant},
                                {"budget", num(m->param, 2) + " vpx"},
                                {"motion_ms", num(m->motion.ms)},
                                {"speedup", num(m->motion.speedupVsFastestExact, 2) + "×"},
                                {"psnr", num(m->motion.psnrMin, 1)},
                                {"differing", pct(m->motion.differingShare)},
                                {"bakes", num(m->motion.bakes, 1)},
                                {"cache_mb", m->motion.cacheBytes > 0
                                                 ? num(m->motion.cacheBytes / 1048576.0, 2)
                                                 : std::string("–")},
                                {"pareto", front.count(m) ? "P" : ""}});
        const bool referenceFaster = ref->motion.ms > 0 && ref->motion.ms < vk->motion.ms;
        scenes.push_back({{"scene", scene},
                          {"fastest", referenceFaster ? "near_reference" : "near_vulkan"},
                          {"fastest_ms", num(referenceFaster ? ref->motion.ms : vk->motion.ms)},
                          {"rows", rows}});
    }
    if (scenes.empty()) return false;
    return {{"scenes", scenes}, {"plot", plotted ? json("frontier.png") : json(false)}};
}

json throughputContext(const SuiteResults& r) {
    json rows = json::array();
    for (const Measurement& m : r.rows) {
        if (m.group != kModesGroup) continue;
        auto rate = [](double v, const char* unit) { return v > 0 ? mega(v) + unit : "–"; };
        rows.push_back(
            {{"scene", m.scene},
             {"mode", toString(m.mode)},
             {"cold_bakes", num(m.cold.bakes, 0)},
             {"cold_bake_ms", num(m.cold.bakeMs, 1)},
             {"rays_per_s", rate(m.cold.raysPerS, " M")},
             {"voxel_steps_per_s", rate(m.voxelStepsPerS, " M")},
             {"blit_mpx_per_s", rate(m.blitPixelsPerS, "")},
             {"memcpy_mpx_per_s", rate(m.memcpyPixelsPerS, "")},
             {"blit_over_memcpy",
              m.memcpyPixelsPerS > 0 ? pct(m.blitPixelsPerS / m.memcpyPixelsPerS, 1) : "–"},
             {"cache_mb", num(perFrame(m, "cache_bytes") / 1048576.0, 2)}});
    }
    return rows;
}

/// The sweep table of the first scene (its modes, then the sweep points), Pareto front marked.
json sweepsContext(const SuiteResults& r, const std::string& scene, bool plotted,
                   bool motionPlotted) {
    std::vector<const Measurement*> sweep;
    for (const Measurement& m : r.rows)
        if (m.group == "sweep" || (m.group == kModesGroup && m.scene == scene)) sweep.push_back(&m);
    if (std::none_of(sweep.begin(), sweep.end(), [](auto* m) { return m->group == "sweep"; }))
        return false;
    std::set<const Measurement*> onFront;
    for (std::size_t i : paretoFront(sweep, mismatchOf)) onFront.insert(sweep[i]);
    const Measurement* hyb = find(r, kModesGroup, scene, BenchMode::Hybrid);
    json rows = json::array();
    for (const Measurement* m : sweep)
        rows.push_back(
            {{"family", m->group == kModesGroup ? "mode" : m->family},
             {"setting", m->setting.empty() ? toString(m->mode) : m->setting},
             {"entities", entitiesCell(*m)},
             {"frame_ms", num(m->frameMs())},
             {"speedup", speedupCell(*m)},
             {"near_share", m->mode == BenchMode::NearReference ? "–" : nearShareCell(*m)},
             {"error", errorCells(*m)},
             {"pareto", onFront.count(m) ? "P" : ""}});
    for (std::size_t i = 0; i < sweep.size(); ++i) rows[i].update(motionCells(*sweep[i]));
    return {{"scene", scene},
            {"selector", hyb ? hyb->selector : ""},
            {"plot", plotted ? json("speed_error.png") : json(false)},
            {"motion_plot", motionPlotted ? json("motion_error.png") : json(false)},
            {"rows", rows}};
}

json scalingContext(const SuiteResults& r, const std::vector<std::string>& plots) {
    struct Curve {
        const char* group;
        const char* title;
        const char* what;
    };
    json out = json::array();
    for (const Curve& c : {Curve{"scaling_entities", "Scaling: entity count", "entities"},
                           Curve{"scaling_size", "Scaling: model size", "model"}}) {
        json rows = json::array();
        // Each mode's frame against its own frame at the curve's first point: how the cost grows.
        std::map<std::string, double> firstMs;
        for (const Measurement& m : r.rows)
            if (m.group == c.group) firstMs.emplace(toString(m.mode), m.frameMs());
        for (const Measurement& m : r.rows)
            if (m.group == c.group)
                rows.push_back(
                    {{"setting", m.setting},
                     {"mode", toString(m.mode)},
                     {"entities", entitiesCell(m)},
                     {"frame_ms", num(m.frameMs())},
                     {"growth", num(m.frameMs() / firstMs[toString(m.mode)], 1) + "×"},
                     {"speedup", speedupCell(m)},
                     {"setup_ms",
                      num(perFrame(m, "host_setup_ms") + perFrame(m, "host_select_ms"))},
                     {"occluded", num(perFrame(m, "near_occluded"), 0) + " / " +
                                      num(perFrame(m, "far_occluded"), 0)},
                     {"near_written", num(perFrame(m, "near_pixels_written"), 0)},
                     {"blit_written", num(perFrame(m, "blit_pixels_written"), 0)},
                     {"near_ms", num(perFrame(m, "near_ms"))},
                     {"near_fragments", num(perFrame(m, "near_fragments"), 0)},
                     {"voxel_steps", num(perFrame(m, "voxel_steps"), 0)},
                     {"blit_ms", num(perFrame(m, "far_blit_ms"))},
                     {"blit_pixels", num(perFrame(m, "blit_pixels"), 0)},
                     {"cold_bake_ms", num(m.cold.bakeMs, 1)},
                     {"error",
                      m.hasError ? json({{"mismatch", pct(m.error.mismatchMean)}}) : json(false)}});
        if (rows.empty()) continue;
        const std::string png = std::string(c.group) + ".png";
        const bool plotted = std::find(plots.begin(), plots.end(), png) != plots.end();
        out.push_back({{"title", c.title},
                       {"what", c.what},
                       {"plot", plotted ? json(png) : json(false)},
                       {"rows", rows}});
    }
    return out;
}

json reportContext(const SuiteResults& r, const PlotSet& plots) {
    const Plan& p = r.plan;
    const std::time_t now = std::time(nullptr);
    char date[64];
    std::strftime(date, sizeof date, "%Y-%m-%d %H:%M UTC", std::gmtime(&now));
    const std::string first = r.rows.empty() ? "" : r.rows.front().scene;
    const bool speedErrorPlot = std::count(plots.pngs.begin(), plots.pngs.end(), "speed_error.png");
    const bool motionErrorPlot =
        std::count(plots.pngs.begin(), plots.pngs.end(), "motion_error.png");
    json context = {{"preset", p.name},
                    {"lead", leadLines(r, /*markdown=*/true)},
                    {"date", date},
                    {"wall_s", num(r.wallSeconds, 0)},
                    {"cpu", r.cpu},
                    {"threads", std::to_string(r.threads)},
                    {"vulkan_device", r.vulkanDevice},
                    {"warmup", std::to_string(p.warmup)},
                    {"repeats", std::to_string(p.repeats)},
                    {"path_frames", std::to_string(p.pathFrames)},
                    {"motion_frames", std::to_string(p.motionFrames)},
                    {"motion_warmup", std::to_string(p.motionWarmup)},
                    {"scaling_repeats", std::to_string(p.scalingRepeats)},
                    {"headline", headlineContext(r, first)},
                    {"baselines", baselinesContext(r)},
                    {"far_blit", r.plan.frame.farBlit.kernel == FarBlitKernel::Simd
                                     ? std::string("SIMD, ") + farBlitSimdTarget()
                                     : std::string("scalar")},
                    {"scenes", modesContext(r)},
                    {"budget_target", budgetTargetContext(r)},
                    {"frontier", frontierContext(r, std::count(plots.pngs.begin(), plots.pngs.end(),
                                                               "frontier.png"))},
                    {"blit_bytes_per_pixel", num(kBlitBytesPerPixel, 0)},
                    {"memcpy_gbps", num(r.memcpyGBps, 1)},
                    {"throughput", throughputContext(r)},
                    {"sweeps", sweepsContext(r, first, speedErrorPlot, motionErrorPlot)},
                    {"scaling", scalingContext(r, plots.pngs)},
                    {"plot_note", plots.note.empty() ? json(false) : json(plots.note)},
                    {"notes", r.notes},
                    {"plots", plots.pngs}};
    context.update(timeSplitContext(r));
    return context;
}

kainjow::mustache::data mustacheData(const json& j) {
    using kainjow::mustache::data;
    switch (j.type()) {
    case json::value_t::object: {
        data d;
        for (const auto& [key, value] : j.items()) d.set(key, mustacheData(value));
        return d;
    }
    case json::value_t::array: {
        data d(data::type::list);
        for (const json& v : j) d.push_back(mustacheData(v));
        return d;
    }
    case json::value_t::string:
        return data(j.get<std::string>());
    case json::value_t::boolean:
        return data(j.get<bool>());
    case json::value_t::null:
        return data(false);
    default:
        return data(j.dump());
    }
}

/// The report template filled with `context`, blank lines left by empty sections collapsed.
std::string renderReport(const json& context) {
    kainjow::mustache::mustache tmpl(kBenchReportTemplate);
    if (!tmpl.is_valid())
        throw std::logic_error("apps/bench/report.md.mustache: " + tmpl.error_message());
    tmpl.set_custom_escape([](const std::string& s) { return s; }); // markdown, not HTML
    const std::string text = tmpl.render(mustacheData(context));
    if (!tmpl.is_valid())
        throw std::logic_error("apps/bench/report.md.mustache: " + tmpl.error_message());
    const std::string collapsed = std::regex_replace(text, std::regex("\n{3,}"), "\n\n");
    return collapsed.substr(std::min(collapsed.find_first_not_of('\n'), collapsed.size()));
}

} // namespace

std::vector<std::string> writeReport(const SuiteResults& r, const std::filesystem::path& dir) {
    std::vector<std::string> written;
    const PlotSet plots = drawPlots(r, dir);
    for (const std::string& png : plots.pngs) written.push_back((dir / png).string());
    writeFileWhole(dir / "report.md", renderReport(reportContext(r, plots)));
    written.push_back((dir / "report.md").string());
    return written;
}

} // namespace voxtier::bench
