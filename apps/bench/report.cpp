// `voxtier bench` output (apps/bench/report.hpp): results.csv and results.json from one list of
// columns (the frame figures among them from compose/frame_figures.hpp), the plots drawn by
// apps/bench/plots.gp from results.csv, report.md filled into apps/bench/report.md.mustache.
// Both files are embedded in the binary at build time (apps/CMakeLists.txt).
#include "apps/bench/report.hpp"

#include "core/error.hpp"
#include "embedded/bench_plots_gp.h"
#include "embedded/bench_report_template.h"
#include "impostor_cache/far_blit.hpp"

#include <kainjow/mustache.hpp>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <regex>
#include <set>

namespace voxtier::bench {

namespace {

namespace fs = std::filesystem;
using nlohmann::json;

std::string num(double v, int decimals = 2) {
    if (std::isinf(v)) return v > 0 ? "inf" : "-inf";
    if (std::isnan(v)) return "nan";
    char buf[64];
    std::snprintf(buf, sizeof buf, "%.*f", decimals, v);
    return buf;
}
std::string pct(double fraction, int decimals = 2) {
    return num(100.0 * fraction, decimals) + " %";
}
/// Significant digits, for the CSV.
std::string sig(double v) {
    if (std::isinf(v)) return v > 0 ? "inf" : "-inf";
    char buf[64];
    std::snprintf(buf, sizeof buf, "%.6g", v);
    return buf;
}
std::string mega(double v) {
    return num(v / 1e6, 1);
}

std::string csvField(const std::string& s) {
    if (s.find_first_of(",\"\n") == std::string::npos) return s;
    std::string q = "\"";
    for (char c : s) q += c == '"' ? std::string("\"\"") : std::string(1, c);
    return q + "\"";
}

void writeFile(const fs::path& p, const std::string& text) {
    std::ofstream out(p);
    if (!out) throw InputError(p.string(), "--out", "cannot open for writing");
    out << text;
    if (!out) throw InputError(p.string(), "--out", "write failed");
}

double mismatchOf(const Measurement& m) {
    return m.hasError ? m.mismatchMean : 0.0;
}
double displacementOf(const Measurement& m) {
    return m.hasError ? m.displacementWorstCells : 0.0;
}

bool isErrorSelector(const Measurement& m) {
    return m.selector.rfind("error_px", 0) == 0;
}

const char* kModesGroup = "modes";

// ---------------------------------------------------------------------------------------------
// The goal of the hybrid frame (10x all-near within the error budget): the goal table's ✓/✗ and the
// choice of the best error-selector setting "within the error budget" both read it.

struct Goals {
    double minSpeedup = 10.0;      ///< against all-near on Vulkan
    double maxMeanMismatch = 0.02; ///< mean footprint mismatch
    /// Far entities displaced by more than one virtual pixel (drawn alone), per frame.
    double maxFarOverOneCell = 0.0;
};
constexpr Goals kGoals;

bool fastEnough(const Measurement& m) {
    return m.speedup >= kGoals.minSpeedup;
}
bool closeEnough(const Measurement& m) {
    return m.mismatchMean <= kGoals.maxMeanMismatch;
}
bool steadyEnough(const Measurement& m) {
    return m.farOverOneCell <= kGoals.maxFarOverOneCell;
}
std::string verdict(bool met) {
    return met ? " ✓" : " ✗";
}

// ---------------------------------------------------------------------------------------------
// results.csv and results.json: one list of columns. A JSON row holds every column, typed, except
// the error columns, which go into the row's "error" object (null for the truth).

struct Column {
    enum class In { Both, CsvOnly, ErrorObject };
    std::string name;
    std::function<json(const Measurement&)> value;
    In in = In::Both;
};

template <class T> std::function<json(const Measurement&)> field(T Measurement::*f) {
    return [f](const Measurement& m) { return json(m.*f); };
}

std::vector<Column> columns() {
    using In = Column::In;
    std::vector<Column> c = {
        {"group", field(&Measurement::group)},
        {"scene", field(&Measurement::scene)},
        {"mode", [](const Measurement& m) { return json(toString(m.mode)); }},
        {"family", field(&Measurement::family)},
        {"setting", field(&Measurement::setting)},
        {"param", field(&Measurement::param)},
        {"selector", field(&Measurement::selector)},
        {"truth", field(&Measurement::truth)},
        {"frames", [](const Measurement& m) { return json(m.frames.size()); }, In::CsvOnly},
    };
    for (std::size_t i = 0; i < kFrameFigureCount; ++i)
        c.push_back({kFrameFigures[i].name,
                     [i](const Measurement& m) { return json(m.figures.values[i]); }});
    const std::vector<Column> bench = {
        {"visible", field(&Measurement::visible)},
        {"worst_frame_ms", field(&Measurement::worstFrameMs)},
        {"all_near_vulkan_ms", field(&Measurement::baselineMs)},
        {"speedup_vs_all_near_vulkan", field(&Measurement::speedup)},
        {"near_vulkan_fragment_ms", field(&Measurement::fragmentMs)},
        {"speedup_vs_near_vulkan_fragment", field(&Measurement::speedupVsFragment)},
        {"all_near_vulkan_fragments", field(&Measurement::baselineFragments)},
        {"voxel_steps_per_s", field(&Measurement::voxelStepsPerS)},
        {"blit_pixels_per_s", field(&Measurement::blitPixelsPerS)},
        {"memcpy_pixels_per_s", field(&Measurement::memcpyPixelsPerS)},
        {"in_motion_ms", field(&Measurement::motionMs)},
        {"in_motion_mean_ms", field(&Measurement::motionMeanMs)},
        {"in_motion_p90_ms", field(&Measurement::motionP90Ms)},
        {"in_motion_worst_ms", field(&Measurement::motionWorstMs)},
        {"in_motion_cold_ms", field(&Measurement::motionColdMs)},
        {"in_motion_all_near_vulkan_ms", field(&Measurement::motionBaselineMs)},
        {"in_motion_speedup_vs_all_near_vulkan", field(&Measurement::motionSpeedup)},
        {"in_motion_all_near_reference_ms", field(&Measurement::motionReferenceMs)},
        {"in_motion_speedup_vs_all_near_reference", field(&Measurement::motionSpeedupVsReference)},
        {"in_motion_fastest_exact_ms", field(&Measurement::motionFastestExactMs)},
        {"in_motion_speedup_vs_fastest_exact", field(&Measurement::motionSpeedupVsFastestExact)},
        {"near_backend", field(&Measurement::nearBackend)},
        {"far_backend", field(&Measurement::farBackend)},
        {"snapshot_scale", field(&Measurement::snapshotScale)},
        {"in_motion_bakes_per_frame", field(&Measurement::motionBakes)},
        {"in_motion_bake_ms_per_frame", field(&Measurement::motionBakeMs)},
        {"in_motion_cache_bytes", field(&Measurement::motionCacheBytes)},
        {"in_motion_near_ms", field(&Measurement::motionNearMs)},
        {"in_motion_near_entities", field(&Measurement::motionNearEntities)},
        {"in_motion_far_entities", field(&Measurement::motionFarEntities)},
        {"in_motion_psnr_min", field(&Measurement::motionPsnrMin)},
        {"in_motion_differing_share", field(&Measurement::motionDifferingShare)},
        {"in_motion_psnr_min_differing_pixels", field(&Measurement::motionPsnrMinPixels)},
        {"in_motion_psnr_min_far_entities", field(&Measurement::motionPsnrMinFar)},
        {"in_motion_predicted_worst_vpx", field(&Measurement::motionPredictedWorstVpx)},
        {"cold_first_frame_ms", field(&Measurement::coldMs)},
        {"cold_bake_ms", field(&Measurement::coldBakeMs)},
        {"cold_bakes", field(&Measurement::coldBakes)},
        {"cold_rays", field(&Measurement::coldRays)},
        {"rays_per_s", field(&Measurement::raysPerS)},
        {"has_error", field(&Measurement::hasError)},
        {"mismatch_mean", field(&Measurement::mismatchMean), In::ErrorObject},
        {"mismatch_worst", field(&Measurement::mismatchWorst), In::ErrorObject},
        {"coverage_mismatch_mean", field(&Measurement::coverageMismatchMean), In::ErrorObject},
        {"far_mismatch_mean", field(&Measurement::farMismatchMean), In::ErrorObject},
        {"far_alone_mismatch_mean", field(&Measurement::farIsolatedMismatchMean), In::ErrorObject},
        {"far_displacement_worst_px", field(&Measurement::displacementWorstPx), In::ErrorObject},
        {"far_displacement_worst_vpx", field(&Measurement::displacementWorstCells),
         In::ErrorObject},
        {"far_visible_displacement_worst_px", field(&Measurement::farVisibleDisplacementWorstPx),
         In::ErrorObject},
        {"far_alone_entities", field(&Measurement::farAloneEntities), In::ErrorObject},
        {"far_displaced_over_1_vpx", field(&Measurement::farOverOneCell), In::ErrorObject},
        {"rmse_mean", field(&Measurement::rmseMean), In::ErrorObject},
        {"psnr_min", field(&Measurement::psnrMin), In::ErrorObject},
        {"differing_pixels", field(&Measurement::differingPixels), In::ErrorObject},
        {"missing_entities", field(&Measurement::missing), In::ErrorObject},
    };
    c.insert(c.end(), bench.begin(), bench.end());
    return c;
}

std::string csvText(const json& v) {
    if (v.is_string()) return csvField(v.get<std::string>());
    if (v.is_boolean()) return v.get<bool>() ? "1" : "0";
    if (v.is_number_float()) return sig(v.get<double>());
    return v.is_null() ? "" : v.dump();
}

std::string toCsv(const SuiteResults& r) {
    const auto cols = columns();
    std::string out;
    for (const Column& c : cols) out += (&c == &cols.front() ? "" : ",") + c.name;
    out += "\n";
    for (const Measurement& m : r.rows) {
        for (const Column& c : cols) out += (&c == &cols.front() ? "" : ",") + csvText(c.value(m));
        out += "\n";
    }
    return out;
}

json summaryJson(const EntityErrorSummary& s) {
    return {{"entities", s.entities},
            {"mismatch_mean", s.meanMismatch},
            {"mismatch_worst", s.worstMismatch},
            {"mismatch_worst_entity", s.worstMismatchEntity},
            {"displacement_mean_px", s.meanDisplacementPx},
            {"displacement_worst_px", s.worstDisplacementPx},
            {"displacement_worst_vpx", s.worstDisplacementCells},
            {"displacement_worst_entity", s.worstDisplacementEntity},
            {"displaced_over_1_vpx", s.overOneCell},
            {"coverage_mismatch_mean", s.meanCoverageMismatch},
            {"missing", s.missing}};
}

/// One sampled path frame: its figures (medians over the passes), typed, and its error.
json frameJson(const FrameRow& f) {
    json fr = {
        {"frame", f.frame}, {"time", f.time}, {"frame_ms_min", f.minMs}, {"frame_ms_max", f.maxMs}};
    for (const FrameFigure& fig : kFrameFigures)
        fr[fig.name] = std::visit([&](auto member) { return json(f.median.*member); }, fig.member);
    fr["error"] = nullptr;
    if (f.hasError)
        fr["error"] = {{"all", summaryJson(f.error.all)},
                       {"far", summaryJson(f.error.far)},
                       {"far_alone", summaryJson(f.error.farIsolated)},
                       {"rmse", f.error.rmse},
                       {"psnr", f.error.psnr},
                       {"changed_pixels", f.error.changedPixels},
                       {"differing_pixels", f.error.differingPixels}};
    return fr;
}

json rowJson(const Measurement& m, const std::vector<Column>& cols) {
    json row, error;
    for (const Column& c : cols) {
        if (c.in == Column::In::Both) row[c.name] = c.value(m);
        if (c.in == Column::In::ErrorObject) error[c.name] = c.value(m);
    }
    row["error"] = m.hasError ? error : json(nullptr);
    row["frames"] = json::array();
    for (const FrameRow& f : m.frames) row["frames"].push_back(frameJson(f));
    return row;
}

json scaleNames(const Plan& p) {
    json names = json::array();
    for (int k : p.snapshotScales) names.push_back(scaleName(k));
    return names;
}

json planJson(const Plan& p) {
    json plan = {{"preset", p.preset},
                 {"repeats", p.repeats},
                 {"warmup", p.warmup},
                 {"path_frames", p.pathFrames},
                 {"motion_frames", p.motionFrames},
                 {"motion_warmup", p.motionWarmup},
                 {"scaling_repeats", p.scalingRepeats},
                 {"entity_counts", p.entityCounts},
                 {"model_sides", p.modelSides},
                 {"size_curve_entities", p.sizeEntities},
                 {"sweeps",
                  {{"far_at_distance", p.distanceFarAt},
                   {"far_at_radius_px", p.radiusFarAt},
                   {"far_at_error_px", p.errorFarAt},
                   {"budgets_vpx", p.budgets},
                   {"snapshot_scales", scaleNames(p)},
                   {"view_sets", p.viewSets},
                   {"sigmas", p.sigmas},
                   {"crossfade_frames", p.crossfades}}}};
    if (p.width) plan["size"] = {*p.width, *p.height};
    if (p.entityCap) plan["entity_cap"] = *p.entityCap;
    if (p.budgetVpx) plan["budget_vpx"] = *p.budgetVpx;
    plan["far_blit"] = p.farBlit == FarBlitKernel::Simd ? "simd" : "scalar";
    plan["far_backend"] = toString(p.farBackend);
    plan["occlusion_cull"] = p.occlusionCull;
    plan["early_depth_test"] = p.earlyDepthTest;
    return plan;
}

json toJson(const SuiteResults& r, const std::vector<std::string>& plots,
            const std::string& plotNote) {
    const auto cols = columns();
    json rows = json::array();
    for (const Measurement& m : r.rows) rows.push_back(rowJson(m, cols));
    json modes = json::array(), figures = json::array();
    for (const BenchModeInfo& mode : kBenchModes) modes.push_back(mode.name);
    for (const FrameFigure& f : kFrameFigures)
        figures.push_back({{"name", f.name},
                           {"unit", toString(f.unit)},
                           {"across_frames", toString(f.acrossFrames)}});
    return {
        {"voxtier_bench", 1},
        {"modes", modes},
        {"ground_truth",
         "near_vulkan: every entity drawn by the Vulkan near tier, same frame; errors of the "
         "other modes are measured against it (near_reference must differ in 0 pixels)"},
        {"frame_figures", figures},
        {"plan", planJson(r.plan)},
        {"scenes", r.scenes},
        {"machine", {{"cpu", r.cpu}, {"threads", r.threads}, {"vulkan_device", r.vulkanDevice}}},
        {"wall_seconds", r.wallSeconds},
        {"memcpy_GBps", r.memcpyGBps},
        {"rows", rows},
        {"plots", plots},
        {"plot_note", plotNote},
        {"notes", r.notes}};
}

// ---------------------------------------------------------------------------------------------
// Plots: apps/bench/plots.gp reads results.csv; the bench writes it into the output folder after
// the settings it needs, with the Pareto fronts it cannot work out itself.

std::string shellQuote(const std::string& s) {
    std::string q = "'";
    for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
    return q + "'";
}

/// A gnuplot single-quoted string ('' stands for a quote).
std::string gnuplotQuote(const std::string& s) {
    std::string q = "'";
    for (char c : s) q += c == '\'' ? std::string("''") : std::string(1, c);
    return q + "'";
}
/// A gnuplot double-quoted string (backslash escapes).
std::string gnuplotDoubleQuote(const std::string& s) {
    std::string q = "\"";
    for (char c : s) q += c == '"' || c == '\\' ? "\\" + std::string(1, c) : std::string(1, c);
    return q + "\"";
}

// ---------------------------------------------------------------------------------------------
// The speed–error frontier: the error_budget sweep in motion, one curve per snapshot scale, each
// point's speed-up against the fastest exact path of its scene against its min PSNR.

/// Identical frames have an infinite PSNR; a plot draws them at 99 dB.
double plottedPsnr(double psnr) {
    return std::min(psnr, 99.0);
}

struct FrontierCurve {
    std::string variant;                    ///< "x3": the snapshot scale
    std::vector<const Measurement*> points; ///< by budget
};

/// The error_budget sweep points of `scene` measured in motion, one curve per snapshot scale of the
/// plan (in its order), each along the budget.
std::vector<FrontierCurve> frontierCurves(const SuiteResults& r, const std::string& scene) {
    std::vector<FrontierCurve> curves;
    for (int k : r.plan.snapshotScales) {
        FrontierCurve c{scaleName(k), {}};
        for (const Measurement& m : r.rows)
            if (m.scene == scene && m.family == kBudgetFamily &&
                m.motionSpeedupVsFastestExact > 0 && m.snapshotScale == k)
                c.points.push_back(&m);
        std::sort(c.points.begin(), c.points.end(),
                  [](const Measurement* a, const Measurement* b) { return a->param < b->param; });
        if (!c.points.empty()) curves.push_back(c);
    }
    return curves;
}

/// The points of `curves` that no other point beats on both speed-up and min PSNR (higher is
/// better on both).
std::set<const Measurement*> frontierPareto(const std::vector<FrontierCurve>& curves) {
    std::vector<const Measurement*> all;
    for (const FrontierCurve& c : curves) all.insert(all.end(), c.points.begin(), c.points.end());
    std::set<const Measurement*> front;
    for (const Measurement* a : all) {
        // The fastest exact path is a point of the frontier too, at 1x with no error: nothing
        // at or below its speed can be on the frontier.
        if (!(a->motionSpeedupVsFastestExact > 1.0)) continue;
        const bool dominated = std::any_of(all.begin(), all.end(), [&](const Measurement* b) {
            const double sa = a->motionSpeedupVsFastestExact, sb = b->motionSpeedupVsFastestExact;
            const double pa = a->motionPsnrMin, pb = b->motionPsnrMin;
            return sb >= sa && pb >= pa && (sb > sa || pb > pa);
        });
        if (!dominated) front.insert(a);
    }
    return front;
}

/// frontier.dat: one block per curve of "speed-up psnr budget" lines; frontier_pareto.dat: the
/// Pareto frontier's points along the speed-up.
void writeFrontierData(const std::vector<FrontierCurve>& curves, const fs::path& dir) {
    std::string data, pareto;
    const std::set<const Measurement*> front = frontierPareto(curves);
    std::vector<const Measurement*> frontPoints(front.begin(), front.end());
    std::sort(frontPoints.begin(), frontPoints.end(), [](auto* a, auto* b) {
        return a->motionSpeedupVsFastestExact < b->motionSpeedupVsFastestExact;
    });
    const auto line = [](const Measurement& m) {
        return sig(m.motionSpeedupVsFastestExact) + " " + sig(plottedPsnr(m.motionPsnrMin));
    };
    for (const FrontierCurve& c : curves) {
        for (const Measurement* m : c.points) data += line(*m) + " " + sig(m->param) + "\n";
        data += "\n\n"; // gnuplot's `index` separator
    }
    for (const Measurement* m : frontPoints) pareto += line(*m) + "\n";
    writeFile(dir / "frontier.dat", data);
    writeFile(dir / "frontier_pareto.dat", pareto);
}

struct PlotSet {
    std::vector<std::string> pngs;
    std::string note; ///< why plots are missing, if they are
};

/// The speed/error points of the first scene: its modes and the sweep points with an error.
std::vector<const Measurement*> speedErrorPoints(const SuiteResults& r, const std::string& scene) {
    std::vector<const Measurement*> pts;
    for (const Measurement& m : r.rows)
        if (m.scene == scene && (m.group == kModesGroup || (m.group == "sweep" && m.hasError)))
            pts.push_back(&m);
    return pts;
}

/// The Pareto front of `pts` on `error`, along increasing error (decreasing time): the staircase
/// bounding what was reached, as "error frame_ms" lines.
std::string paretoData(const std::vector<const Measurement*>& pts,
                       double (*error)(const Measurement&), double errorScale) {
    auto front = paretoFront(pts, error);
    std::reverse(front.begin(), front.end());
    std::string out;
    for (std::size_t i : front)
        out += sig(errorScale * error(*pts[i])) + " " + sig(pts[i]->frameMs()) + "\n";
    return out;
}

/// The settings plots.gp starts from (its header says what each means).
std::string plotSettings(const SuiteResults& r, const std::string& scene,
                         const std::vector<std::string>& pngs) {
    std::string modes, families, variants, plots;
    for (const BenchModeInfo& mode : kBenchModes)
        modes += std::string(modes.empty() ? "" : " ") + mode.name;
    std::set<std::string> seen;
    for (const Measurement* m : speedErrorPoints(r, scene))
        if (m->group != kModesGroup && seen.insert(m->family).second)
            families += (families.empty() ? "" : " ") + gnuplotQuote(m->family);
    for (const FrontierCurve& c : frontierCurves(r, scene))
        variants += (variants.empty() ? "" : " ") + gnuplotQuote(c.variant);
    for (const std::string& png : pngs)
        plots += (plots.empty() ? "" : " ") + fs::path(png).stem().string();
    return "scene = " + gnuplotQuote(scene) + "\nmodes = " + gnuplotQuote(modes) +
           "\nfamilies = " + gnuplotDoubleQuote(families) +
           "\nvariants = " + gnuplotDoubleQuote(variants) + "\nplots = " + gnuplotQuote(plots) +
           "\n\n";
}

PlotSet drawPlots(const SuiteResults& r, const fs::path& dir) {
    PlotSet out;
    if (std::system("command -v gnuplot >/dev/null 2>&1") != 0) {
        out.note = "gnuplot was not found on PATH (install gnuplot-nox; tools/setup.sh does), so "
                   "no plots were drawn; the tables and results.csv hold every number.";
        return out;
    }
    const std::string scene = r.rows.empty() ? "" : r.rows.front().scene;
    const auto pts = speedErrorPoints(r, scene);
    if (!pts.empty()) out.pngs.push_back("speed_error.png");
    if (std::any_of(pts.begin(), pts.end(), [](const Measurement* m) { return m->motionMs > 0; }))
        out.pngs.push_back("motion_error.png");
    const std::vector<FrontierCurve> curves = frontierCurves(r, scene);
    if (!curves.empty()) out.pngs.push_back("frontier.png");
    for (const char* group : {"scaling_entities", "scaling_size"})
        if (std::any_of(r.rows.begin(), r.rows.end(),
                        [&](const Measurement& m) { return m.group == group; }))
            out.pngs.push_back(std::string(group) + ".png");
    writeFile(dir / "pareto_mismatch.dat", paretoData(pts, mismatchOf, 100.0));
    writeFile(dir / "pareto_displacement.dat", paretoData(pts, displacementOf, 1.0));
    writeFrontierData(curves, dir);
    writeFile(dir / "plots.gp", plotSettings(r, scene, out.pngs) + kBenchPlotsGp);
    const std::string cmd =
        "cd " + shellQuote(dir.string()) + " && gnuplot plots.gp > plots.log 2>&1";
    const int rc = std::system(cmd.c_str());
    std::vector<std::string> ok;
    for (const std::string& png : out.pngs)
        if (fs::exists(dir / png) && fs::file_size(dir / png) > 0) ok.push_back(png);
    if (rc != 0 || ok.size() != out.pngs.size())
        out.note = "gnuplot failed (exit " + std::to_string(rc) + ", see plots.log); " +
                   std::to_string(ok.size()) + " of " + std::to_string(out.pngs.size()) +
                   " plots were drawn.";
    out.pngs = ok;
    return out;
}

// ---------------------------------------------------------------------------------------------
// report.md: the template's context, every number formatted here.

const Measurement* find(const SuiteResults& r, const std::string& group, const std::string& scene,
                        BenchMode mode) {
    for (const Measurement& m : r.rows)
        if (m.group == group && m.scene == scene && m.mode == mode) return &m;
    return nullptr;
}

std::vector<std::string> sceneNames(const SuiteResults& r) {
    std::vector<std::string> out;
    for (const Measurement& m : r.rows)
        if (m.group == kModesGroup && std::find(out.begin(), out.end(), m.scene) == out.end())
            out.push_back(m.scene);
    return out;
}

double perFrame(const Measurement& m, FrameMember member) {
    return m.figures.of(member);
}

std::string entitiesCell(const Measurement& m) {
    std::string s = num(perFrame(m, &FrameStats::nearDrawn), 0) + " / " +
                    num(perFrame(m, &FrameStats::farDrawn), 0);
    const double fading = perFrame(m, &FrameStats::fading);
    if (fading >= 0.5) s += " (" + num(fading, 0) + " fading)";
    return s;
}

std::string overOne(const Measurement& m) {
    return m.farAloneEntities > 0 ? num(m.farOverOneCell, 1) + " of " + num(m.farAloneEntities, 0)
                                  : "–";
}

std::string speedupCell(const Measurement& m) {
    return m.speedup > 0 ? num(m.speedup, 1) + "×" : "–";
}

std::string nearShareCell(const Measurement& m) {
    return m.baselineFragments > 0
               ? pct(perFrame(m, &FrameStats::nearPixelsTested) / m.baselineFragments, 1)
               : "–";
}

/// The in-motion cells of a row (issue 13): median / 90th-percentile frame ms after the cold
/// start (cold start), speed-up, bakes per frame, min PSNR and differing pixels against all-near
/// in motion.
json motionCells(const Measurement& m) {
    if (m.motionMs <= 0)
        return {{"motion_ms", "–"},
                {"motion_speedup", "–"},
                {"motion_bakes", "–"},
                {"motion_error", "–"}};
    return {{"motion_ms",
             num(m.motionMs) + " / " + num(m.motionP90Ms) + " (" + num(m.motionColdMs) + ")"},
            {"motion_speedup", m.motionSpeedup > 0 ? num(m.motionSpeedup, 1) + "×" : "–"},
            {"motion_bakes", num(m.motionBakes, 1) + " / " + num(m.motionBakeMs, 1) + " ms"},
            {"motion_error", m.motionPsnrMin > 0 ? num(m.motionPsnrMin, 1) + " dB, " +
                                                       pct(m.motionDifferingShare) + " px"
                                                 : "(truth)"}};
}

/// The error cells of a row, or false for the truth.
json errorCells(const Measurement& m) {
    if (!m.hasError) return false;
    return {{"mismatch", pct(m.mismatchMean) + " (" + pct(m.coverageMismatchMean) + ")"},
            {"worst", pct(m.mismatchWorst)},
            {"displacement",
             num(m.displacementWorstPx, 1) + " px (" + num(m.displacementWorstCells, 2) + ")"},
            {"over_one", overOne(m)},
            {"rmse", num(m.rmseMean, 4)},
            {"psnr", num(m.psnrMin, 1)}};
}

/// One column of the goal table; `missing` fills every cell when there is no such setting.
json goalColumn(const Measurement* m, const std::string& missing) {
    if (!m)
        return {{"setting", missing},
                {"speedup", missing},
                {"mismatch", missing},
                {"displacement", missing},
                {"near_share", missing}};
    const std::string setting = m->mode == BenchMode::Far ? "all far"
                                : m->setting.empty()      ? m->selector
                                                          : m->setting;
    return {{"setting", setting},
            {"speedup", speedupCell(*m) + verdict(fastEnough(*m))},
            {"mismatch", pct(m->mismatchMean) + " (" + pct(m->coverageMismatchMean) + ")" +
                             verdict(closeEnough(*m))},
            {"displacement", "worst " + num(m->displacementWorstCells, 2) + "; " + overOne(*m) +
                                 " per frame" + verdict(steadyEnough(*m))},
            {"near_share", nearShareCell(*m)}};
}

/// The first scene's hybrid against all-near, and the goal table: the hybrid as configured, the
/// fastest error-selector setting within the error budget, the fastest measured setting.
json headlineContext(const SuiteResults& r, const std::string& scene) {
    const Measurement* hyb = find(r, kModesGroup, scene, BenchMode::Hybrid);
    const Measurement* truth = find(r, kModesGroup, scene, BenchMode::NearVulkan);
    if (!hyb || !truth) return false;
    const Measurement* best = nullptr;
    const Measurement* fastest = nullptr;
    for (const Measurement& m : r.rows) {
        if (m.scene != scene || (m.group != kModesGroup && m.group != "sweep") || !m.hasError ||
            m.mode == BenchMode::NearReference)
            continue;
        if (m.mode == BenchMode::Hybrid && isErrorSelector(m) && closeEnough(m) &&
            steadyEnough(m) && (!best || m.speedup > best->speedup))
            best = &m;
        if (!fastest || m.speedup > fastest->speedup) fastest = &m;
    }
    return {{"scene", scene},
            {"selector", hyb->selector},
            {"hybrid_ms", num(hyb->frameMs())},
            {"all_near_ms", num(truth->frameMs())},
            {"speedup", speedupCell(*hyb)},
            {"near_entities", num(perFrame(*hyb, &FrameStats::nearDrawn), 0)},
            {"far_entities", num(perFrame(*hyb, &FrameStats::farDrawn), 0)},
            {"mismatch_mean", pct(hyb->mismatchMean)},
            {"mismatch_worst", pct(hyb->mismatchWorst)},
            {"displacement_px", num(hyb->displacementWorstPx, 1)},
            {"displacement_vpx", num(hyb->displacementWorstCells, 2)},
            {"goals",
             {{"speedup", num(kGoals.minSpeedup, 0) + "×"},
              {"mismatch", pct(kGoals.maxMeanMismatch, 0)}}},
            {"goal_columns",
             {goalColumn(hyb, "–"), goalColumn(best, "none measured"), goalColumn(fastest, "–")}}};
}

/// Per scene, the hybrid in motion against both exact paths (issue 24): all-near on the CPU
/// reference and on Vulkan, which of them is faster on this machine, and the error the speed-up
/// costs, beside the far blit's throughput.
json baselinesContext(const SuiteResults& r) {
    json rows = json::array();
    for (const std::string& scene : sceneNames(r)) {
        const Measurement* h = find(r, kModesGroup, scene, BenchMode::Hybrid);
        const Measurement* ref = find(r, kModesGroup, scene, BenchMode::NearReference);
        const Measurement* vk = find(r, kModesGroup, scene, BenchMode::NearVulkan);
        if (!h || !ref || !vk || h->motionMs <= 0) continue;
        const bool referenceFaster = ref->motionMs > 0 && ref->motionMs < vk->motionMs;
        const double fastestMs = referenceFaster ? ref->motionMs : vk->motionMs;
        rows.push_back(
            {{"scene", scene},
             {"hybrid_ms", num(h->motionMs)},
             {"near_backend", h->nearBackend},
             {"reference_ms", num(ref->motionMs)},
             {"vs_reference",
              h->motionSpeedupVsReference > 0 ? num(h->motionSpeedupVsReference, 1) + "×" : "–"},
             {"vulkan_ms", num(vk->motionMs)},
             {"vs_vulkan", h->motionSpeedup > 0 ? num(h->motionSpeedup, 1) + "×" : "–"},
             {"fastest", referenceFaster ? "near_reference" : "near_vulkan"},
             {"vs_fastest", num(fastestMs / h->motionMs, 1) + "×"},
             {"error", h->motionPsnrMin > 0 ? num(h->motionPsnrMin, 1) + " dB, " +
                                                  pct(h->motionDifferingShare) + " px"
                                            : "–"},
             {"displacement", h->hasError ? num(h->displacementWorstCells, 2) : "–"},
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
                     {"worst_frame_ms", num(m->worstFrameMs)},
                     {"speedup", speedupCell(*m)},
                     {"speedup_vs_fragment",
                      m->speedupVsFragment > 0 ? num(m->speedupVsFragment, 1) + "×" : "–"},
                     {"error", errorCells(*m)}});
                modes.back().update(motionCells(*m));
            }
        const Measurement* ref = find(r, kModesGroup, scene, BenchMode::NearReference);
        scenes.push_back(
            {{"scene", scene},
             {"modes", modes},
             {"reference_differing", ref ? json(num(ref->differingPixels, 0)) : json(false)}});
    }
    return scenes;
}

/// The hybrid frame's steps per scene: the time-step figures, then the rest of frame_ms as
/// "other".
json timeSplitContext(const SuiteResults& r) {
    json rows = json::array();
    for (const std::string& scene : sceneNames(r)) {
        const Measurement* h = find(r, kModesGroup, scene, BenchMode::Hybrid);
        if (!h) continue;
        json steps = json::array();
        double other = h->frameMs();
        for (std::size_t i = 0; i < kFrameFigureCount; ++i)
            if (kFrameFigures[i].timeStep) {
                steps.push_back(num(h->figures.values[i]));
                other -= h->figures.values[i];
            }
        rows.push_back({{"scene", scene},
                        {"steps", steps},
                        {"other", num(other)},
                        {"total", num(h->frameMs())}});
    }
    return rows;
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
/// (DESIGN.md §5; tests/error_budget_test.cpp checks measured ≤ predicted + that allowance).
std::string measuredDisplacement(const Measurement& m) {
    if (!m.hasError || m.farAloneEntities <= 0) return "";
    std::string s =
        " (measured worst " + num(m.displacementWorstCells, 2) + " vpx on the sampled frames";
    if (m.farOverOneCell > 0)
        s += ", " + num(m.farOverOneCell, 1) + " of " + num(m.farAloneEntities, 1) +
             " far entities a frame over 1: both tiers point-sample whole cells, so an outline "
             "moved by less than a cell still flips cells, and a diagonal flip measures √2";
    return s + ")";
}

/// What a PSNR target asks of the budget's worst frame: the squared error is the differing
/// share times the mean squared error of a differing pixel, so at the same error per differing
/// pixel the target allows only share / 10^((target - PSNR) / 10) of the pixels to differ. Far
/// sprites differ from near ones wherever their outline cells move, which any view but an exact
/// one does (DESIGN.md §5), so the allowance per far sprite says whether the target is in reach.
std::string psnrBound(const Measurement& m) {
    const double psnr = m.motionPsnrMin;
    if (!std::isfinite(psnr) || psnr >= kBudgetTarget.minPsnrDb || m.motionPsnrMinPixels <= 0)
        return ""; // (no differing pixel: no share either)
    const double factor = std::pow(10.0, (kBudgetTarget.minPsnrDb - psnr) / 10.0);
    const double pixels = m.motionPsnrMinPixels / factor;
    std::string s =
        num(kBudgetTarget.minPsnrDb, 0) + " dB asks for a " + num(factor, factor < 10.0 ? 2 : 0) +
        "× smaller squared error than the worst frame (" + num(psnr, 1) + " dB, " +
        num(m.motionPsnrMinPixels, 0) + " pixels differing, " + pct(m.motionPsnrMinShare) +
        "): at the same error per differing pixel, " + num(pixels, 0) + " differing pixels";
    if (m.motionPsnrMinFar > 0)
        s += ", " + num(pixels / m.motionPsnrMinFar, 1) + " per far sprite (" +
             num(m.motionPsnrMinFar, 0) +
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
        if (!frag || frag->motionMs <= 0) continue;
        // The budget sweep runs each budget with every snapshot scale; the target is read on the
        // plan's first (the frontier section sets them side by side).
        const int first = r.plan.snapshotScales.empty() ? 1 : r.plan.snapshotScales.front();
        std::vector<const Measurement*> budgets;
        for (const Measurement& m : r.rows)
            if (m.scene == scene && m.family == kBudgetFamily && m.motionMs > 0 &&
                m.snapshotScale == first)
                budgets.push_back(&m);
        if (budgets.empty()) continue;
        std::sort(budgets.begin(), budgets.end(),
                  [](const Measurement* a, const Measurement* b) { return a->param < b->param; });
        const auto ceiling = [&](const Measurement& m) {
            return m.motionNearMs > 0 ? frag->motionMeanMs / m.motionNearMs : 0.0;
        };
        json rows = json::array();
        const Measurement* target = nullptr;
        const Measurement* loosest40 = nullptr; // the largest budget that still reached 40 dB
        const Measurement* sharpest = budgets.front();
        for (const Measurement* m : budgets) {
            if (m->param == kBudgetTarget.budgetVpx) target = m;
            if (m->motionPsnrMin >= kBudgetTarget.minPsnrDb) loosest40 = m;
            if (m->motionPsnrMin > sharpest->motionPsnrMin) sharpest = m;
            rows.push_back(
                {{"budget", num(m->param, 2) + " vpx"},
                 {"entities", num(m->motionNearEntities, 0) + " / " + num(m->motionFarEntities, 0)},
                 {"motion_ms", num(m->motionMs) + " (" + num(m->motionMeanMs) + ")"},
                 {"vs_fragment", num(frag->motionMs / m->motionMs, 2) + "× (" +
                                     num(frag->motionMeanMs / m->motionMeanMs, 2) + "×)"},
                 {"near_ms", num(m->motionNearMs)},
                 {"bake_ms", num(m->motionBakeMs)},
                 {"ceiling", num(ceiling(*m), 2) + "×"},
                 {"error", num(m->motionPsnrMin, 1) + " dB, " + pct(m->motionDifferingShare)},
                 {"predicted", num(m->motionPredictedWorstVpx, 2)}});
        }
        std::string line = "**" + scene + "**: ";
        if (!target) {
            line += "no row at " + num(kBudgetTarget.budgetVpx, 0) + " vpx was measured.";
        } else {
            const double speedup = frag->motionMs / target->motionMs;
            line += "at " + num(kBudgetTarget.budgetVpx, 0) + " vpx, " + num(speedup, 2) +
                    "× the per-pixel frame in motion (median; target ≥ " +
                    num(kBudgetTarget.minSpeedupVsFragment, 0) + "×)" +
                    verdict(speedup >= kBudgetTarget.minSpeedupVsFragment) + ", PSNR min " +
                    num(target->motionPsnrMin, 1) + " dB (target ≥ " +
                    num(kBudgetTarget.minPsnrDb, 0) + ")" +
                    verdict(target->motionPsnrMin >= kBudgetTarget.minPsnrDb) +
                    ", predicted worst " + num(target->motionPredictedWorstVpx, 2) + " vpx" +
                    verdict(target->motionPredictedWorstVpx <= kBudgetTarget.budgetVpx) +
                    measuredDisplacement(*target) + ". The near tier alone takes " +
                    num(target->motionNearMs) + " ms a frame for " +
                    num(target->motionNearEntities, 0) +
                    " near entities, so free far sprites and free bakes would give at most " +
                    num(ceiling(*target), 2) + "× (means). " + psnrBound(*target);
        }
        line += loosest40
                    ? "PSNR ≥ " + num(kBudgetTarget.minPsnrDb, 0) + " dB up to " +
                          num(loosest40->param, 2) + " vpx, where the frame is " +
                          num(frag->motionMs / loosest40->motionMs, 2) + "× per pixel (ceiling " +
                          num(ceiling(*loosest40), 2) + "×)."
                    : "PSNR ≥ " + num(kBudgetTarget.minPsnrDb, 0) +
                          " dB at no budget measured (best " + num(sharpest->motionPsnrMin, 1) +
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
                rows.push_back(
                    {{"variant", c.variant},
                     {"budget", num(m->param, 2) + " vpx"},
                     {"motion_ms", num(m->motionMs)},
                     {"speedup", num(m->motionSpeedupVsFastestExact, 2) + "×"},
                     {"psnr", num(m->motionPsnrMin, 1)},
                     {"differing", pct(m->motionDifferingShare)},
                     {"bakes", num(m->motionBakes, 1)},
                     {"cache_mb", m->motionCacheBytes > 0 ? num(m->motionCacheBytes / 1048576.0, 2)
                                                          : std::string("–")},
                     {"pareto", front.count(m) ? "P" : ""}});
        const bool referenceFaster = ref->motionMs > 0 && ref->motionMs < vk->motionMs;
        scenes.push_back({{"scene", scene},
                          {"fastest", referenceFaster ? "near_reference" : "near_vulkan"},
                          {"fastest_ms", num(referenceFaster ? ref->motionMs : vk->motionMs)},
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
             {"cold_bakes", num(m.coldBakes, 0)},
             {"cold_bake_ms", num(m.coldBakeMs, 1)},
             {"rays_per_s", rate(m.raysPerS, " M")},
             {"voxel_steps_per_s", rate(m.voxelStepsPerS, " M")},
             {"blit_mpx_per_s", rate(m.blitPixelsPerS, "")},
             {"memcpy_mpx_per_s", rate(m.memcpyPixelsPerS, "")},
             {"blit_over_memcpy",
              m.memcpyPixelsPerS > 0 ? pct(m.blitPixelsPerS / m.memcpyPixelsPerS, 1) : "–"},
             {"cache_mb", num(perFrame(m, &FrameStats::cacheBytes) / 1048576.0, 2)}});
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
                     {"setup_ms", num(perFrame(m, &FrameStats::hostSetupMs) +
                                      perFrame(m, &FrameStats::hostSelectMs))},
                     {"occluded", num(perFrame(m, &FrameStats::nearOccluded), 0) + " / " +
                                      num(perFrame(m, &FrameStats::farOccluded), 0)},
                     {"near_written", num(perFrame(m, &FrameStats::nearPixelsWritten), 0)},
                     {"blit_written", num(perFrame(m, &FrameStats::farPixelsWritten), 0)},
                     {"near_ms", num(perFrame(m, &FrameStats::nearMs))},
                     {"near_fragments", num(perFrame(m, &FrameStats::nearPixelsTested), 0)},
                     {"voxel_steps", num(perFrame(m, &FrameStats::voxelFetches), 0)},
                     {"blit_ms", num(perFrame(m, &FrameStats::blitMs))},
                     {"blit_pixels", num(perFrame(m, &FrameStats::farPixelsTested), 0)},
                     {"cold_bake_ms", num(m.coldBakeMs, 1)},
                     {"error",
                      m.hasError ? json({{"mismatch", pct(m.mismatchMean)}}) : json(false)}});
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
    json timeSteps = json::array();
    for (const FrameFigure& f : kFrameFigures)
        if (f.timeStep) timeSteps.push_back(f.words());
    const bool speedErrorPlot = std::count(plots.pngs.begin(), plots.pngs.end(), "speed_error.png");
    const bool motionErrorPlot =
        std::count(plots.pngs.begin(), plots.pngs.end(), "motion_error.png");
    return {{"preset", p.preset},
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
            {"far_blit", r.plan.farBlit == FarBlitKernel::Simd
                             ? std::string("SIMD, ") + farBlitSimdTarget()
                             : std::string("scalar")},
            {"scenes", modesContext(r)},
            {"time_steps", timeSteps},
            {"time_split", timeSplitContext(r)},
            {"budget_target", budgetTargetContext(r)},
            {"frontier",
             frontierContext(r, std::count(plots.pngs.begin(), plots.pngs.end(), "frontier.png"))},
            {"blit_bytes_per_pixel", num(kBlitBytesPerPixel, 0)},
            {"memcpy_gbps", num(r.memcpyGBps, 1)},
            {"throughput", throughputContext(r)},
            {"sweeps", sweepsContext(r, first, speedErrorPlot, motionErrorPlot)},
            {"scaling", scalingContext(r, plots.pngs)},
            {"plot_note", plots.note.empty() ? json(false) : json(plots.note)},
            {"notes", r.notes},
            {"plots", plots.pngs}};
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

std::vector<std::size_t> paretoFront(const std::vector<const Measurement*>& rows,
                                     double (*error)(const Measurement&)) {
    std::vector<std::size_t> front;
    for (std::size_t i = 0; i < rows.size(); ++i) {
        bool dominated = false;
        for (std::size_t j = 0; j < rows.size() && !dominated; ++j) {
            if (i == j) continue;
            const double ti = rows[i]->frameMs(), tj = rows[j]->frameMs(), ei = error(*rows[i]),
                         ej = error(*rows[j]);
            dominated = tj <= ti && ej <= ei && (tj < ti || ej < ei);
        }
        if (!dominated) front.push_back(i);
    }
    std::sort(front.begin(), front.end(), [&](std::size_t a, std::size_t b) {
        return rows[a]->frameMs() < rows[b]->frameMs();
    });
    return front;
}

std::vector<std::string> writeReport(SuiteResults r, const std::string& dirName) {
    const fs::path dir(dirName);
    std::vector<std::string> written;
    writeFile(dir / "results.csv", toCsv(r));
    written.push_back((dir / "results.csv").string());
    const PlotSet plots = drawPlots(r, dir);
    writeFile(dir / "results.json", toJson(r, plots.pngs, plots.note).dump(1) + "\n");
    written.push_back((dir / "results.json").string());
    for (const std::string& p : plots.pngs) written.push_back((dir / p).string());
    writeFile(dir / "report.md", renderReport(reportContext(r, plots)));
    written.push_back((dir / "report.md").string());
    return written;
}

} // namespace voxtier::bench
