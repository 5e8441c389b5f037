// `voxtier bench` output (apps/bench_report.hpp).
#include "apps/bench_report.hpp"

#include "core/error.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <set>
#include <sstream>

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

// ---------------------------------------------------------------------------------------------
// CSV and JSON.

struct Column {
    const char* name;
    std::function<std::string(const Measurement&)> get;
};

std::vector<Column> columns() {
    auto d = [](double Measurement::*f) { return [f](const Measurement& m) { return sig(m.*f); }; };
    auto s = [](std::string Measurement::*f) {
        return [f](const Measurement& m) { return csvField(m.*f); };
    };
    return {
        {"group", s(&Measurement::group)},
        {"scene", s(&Measurement::scene)},
        {"mode", s(&Measurement::mode)},
        {"family", s(&Measurement::family)},
        {"setting", s(&Measurement::setting)},
        {"param", d(&Measurement::param)},
        {"selector", s(&Measurement::selector)},
        {"truth", s(&Measurement::truth)},
        {"frames", [](const Measurement& m) { return std::to_string(m.frames.size()); }},
        {"entities", d(&Measurement::entities)},
        {"visible", d(&Measurement::visible)},
        {"near_entities", d(&Measurement::nearDrawn)},
        {"far_entities", d(&Measurement::farDrawn)},
        {"fading_entities", d(&Measurement::fading)},
        {"frame_ms", d(&Measurement::totalMs)},
        {"worst_frame_ms", d(&Measurement::worstFrameMs)},
        {"all_near_vulkan_ms", d(&Measurement::baselineMs)},
        {"speedup_vs_all_near_vulkan", d(&Measurement::speedup)},
        {"setup_ms", d(&Measurement::setupMs)},
        {"select_ms", d(&Measurement::selectMs)},
        {"near_ms", d(&Measurement::nearMs)},
        {"near_upload_ms", d(&Measurement::nearUploadMs)},
        {"near_draw_ms", d(&Measurement::nearDrawMs)},
        {"near_readback_ms", d(&Measurement::nearReadbackMs)},
        {"far_ms", d(&Measurement::farMs)},
        {"far_lookup_bake_ms", d(&Measurement::bakeMs)},
        {"far_blit_ms", d(&Measurement::blitMs)},
        {"near_fragments", d(&Measurement::fragments)},
        {"voxel_steps", d(&Measurement::voxelSteps)},
        {"voxel_steps_per_s", d(&Measurement::voxelStepsPerS)},
        {"blit_pixels", d(&Measurement::blitPixels)},
        {"blit_pixels_per_s", d(&Measurement::blitPixelsPerS)},
        {"memcpy_pixels_per_s", d(&Measurement::memcpyPixelsPerS)},
        {"cache_bytes", d(&Measurement::cacheBytes)},
        {"cold_first_frame_ms", d(&Measurement::coldMs)},
        {"cold_bake_ms", d(&Measurement::coldBakeMs)},
        {"cold_bakes", d(&Measurement::coldBakes)},
        {"cold_rays", d(&Measurement::coldRays)},
        {"rays_per_s", d(&Measurement::raysPerS)},
        {"has_error", [](const Measurement& m) { return std::string(m.hasError ? "1" : "0"); }},
        {"mismatch_mean", d(&Measurement::mismatchMean)},
        {"mismatch_worst", d(&Measurement::mismatchWorst)},
        {"coverage_mismatch_mean", d(&Measurement::coverageMismatchMean)},
        {"far_mismatch_mean", d(&Measurement::farMismatchMean)},
        {"far_alone_mismatch_mean", d(&Measurement::farIsolatedMismatchMean)},
        {"far_displacement_worst_px", d(&Measurement::displacementWorstPx)},
        {"far_displacement_worst_vpx", d(&Measurement::displacementWorstCells)},
        {"far_visible_displacement_worst_px", d(&Measurement::farVisibleDisplacementWorstPx)},
        {"far_alone_entities", d(&Measurement::farAloneEntities)},
        {"far_displaced_over_1_vpx", d(&Measurement::farOverOneCell)},
        {"all_near_vulkan_fragments", d(&Measurement::baselineFragments)},
        {"rmse_mean", d(&Measurement::rmseMean)},
        {"psnr_min", d(&Measurement::psnrMin)},
        {"differing_pixels", d(&Measurement::differingPixels)},
        {"missing_entities", [](const Measurement& m) { return std::to_string(m.missing); }},
    };
}

std::string toCsv(const SuiteResults& r) {
    const auto cols = columns();
    std::string out;
    for (std::size_t i = 0; i < cols.size(); ++i) out += std::string(i ? "," : "") + cols[i].name;
    out += "\n";
    for (const Measurement& m : r.rows) {
        for (std::size_t i = 0; i < cols.size(); ++i) out += (i ? "," : "") + cols[i].get(m);
        out += "\n";
    }
    return out;
}

json finite(double v) {
    return std::isfinite(v) ? json(v) : json(nullptr);
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

json toJson(const SuiteResults& r, const std::vector<std::string>& plots,
            const std::string& plotNote) {
    json rows = json::array();
    const auto cols = columns();
    for (const Measurement& m : r.rows) {
        json row;
        // The CSV columns, typed.
        row["group"] = m.group, row["scene"] = m.scene, row["mode"] = m.mode,
        row["family"] = m.family;
        row["setting"] = m.setting, row["param"] = m.param, row["selector"] = m.selector,
        row["truth"] = m.truth;
        row["entities"] = m.entities, row["visible"] = m.visible,
        row["near_entities"] = m.nearDrawn;
        row["far_entities"] = m.farDrawn, row["fading_entities"] = m.fading;
        row["frame_ms"] = m.totalMs, row["worst_frame_ms"] = m.worstFrameMs;
        row["all_near_vulkan_fragments"] = m.baselineFragments;
        row["all_near_vulkan_ms"] = m.baselineMs, row["speedup_vs_all_near_vulkan"] = m.speedup;
        row["ms"] = {{"setup", m.setupMs},
                     {"select", m.selectMs},
                     {"near", m.nearMs},
                     {"near_upload", m.nearUploadMs},
                     {"near_draw", m.nearDrawMs},
                     {"near_readback", m.nearReadbackMs},
                     {"far", m.farMs},
                     {"far_lookup_bake", m.bakeMs},
                     {"far_blit", m.blitMs}};
        row["near_fragments"] = m.fragments, row["voxel_steps"] = m.voxelSteps;
        row["voxel_steps_per_s"] = m.voxelStepsPerS, row["blit_pixels"] = m.blitPixels;
        row["blit_pixels_per_s"] = m.blitPixelsPerS,
        row["memcpy_pixels_per_s"] = m.memcpyPixelsPerS;
        row["cache_bytes"] = m.cacheBytes;
        row["cold"] = {{"first_frame_ms", m.coldMs},
                       {"bake_ms", m.coldBakeMs},
                       {"bakes", m.coldBakes},
                       {"rays", m.coldRays},
                       {"rays_per_s", m.raysPerS}};
        if (m.hasError)
            row["error"] = {{"mismatch_mean", m.mismatchMean},
                            {"mismatch_worst", m.mismatchWorst},
                            {"coverage_mismatch_mean", m.coverageMismatchMean},
                            {"far_alone_entities", m.farAloneEntities},
                            {"far_displaced_over_1_vpx", m.farOverOneCell},
                            {"far_mismatch_mean", m.farMismatchMean},
                            {"far_alone_mismatch_mean", m.farIsolatedMismatchMean},
                            {"far_displacement_worst_px", m.displacementWorstPx},
                            {"far_displacement_worst_vpx", m.displacementWorstCells},
                            {"far_visible_displacement_worst_px", m.farVisibleDisplacementWorstPx},
                            {"rmse_mean", m.rmseMean},
                            {"psnr_min", finite(m.psnrMin)},
                            {"differing_pixels", m.differingPixels},
                            {"missing_entities", m.missing}};
        else
            row["error"] = nullptr;
        json frames = json::array();
        for (const FrameRow& f : m.frames) {
            const FrameStats& s = f.median;
            json fr = {{"frame", f.frame},
                       {"time", f.time},
                       {"frame_ms", s.totalMs},
                       {"frame_ms_min", f.minMs},
                       {"frame_ms_max", f.maxMs},
                       {"near_entities", s.nearDrawn},
                       {"far_entities", s.farDrawn},
                       {"fading_entities", s.fading},
                       {"culled", s.culled},
                       {"ms",
                        {{"setup", s.setupMs},
                         {"select", s.selectMs},
                         {"near", s.nearMs},
                         {"near_upload", s.nearUploadMs},
                         {"near_draw", s.nearDrawMs},
                         {"near_readback", s.nearReadbackMs},
                         {"far", s.farMs},
                         {"far_lookup_bake", s.bakeMs},
                         {"far_blit", s.blitMs}}},
                       {"near_fragments", s.nearPixelsTested},
                       {"voxel_steps", m.mode == "near_vulkan" ? f.countedSteps : s.voxelFetches},
                       {"blit_pixels", s.farPixelsTested},
                       {"cache_bytes", s.cacheBytes}};
            if (f.hasError)
                fr["error"] = {{"all", summaryJson(f.error.all)},
                               {"far", summaryJson(f.error.far)},
                               {"far_alone", summaryJson(f.error.farIsolated)},
                               {"rmse", f.error.rmse},
                               {"psnr", finite(f.error.psnr)},
                               {"changed_pixels", f.error.changedPixels},
                               {"differing_pixels", f.error.differingPixels}};
            frames.push_back(fr);
        }
        row["frames"] = frames;
        rows.push_back(row);
    }
    const Plan& p = r.plan;
    json plan = {{"preset", p.preset},
                 {"repeats", p.repeats},
                 {"warmup", p.warmup},
                 {"path_frames", p.pathFrames},
                 {"scaling_repeats", p.scalingRepeats},
                 {"entity_counts", p.entityCounts},
                 {"model_sides", p.modelSides},
                 {"size_curve_entities", p.sizeEntities},
                 {"sweeps",
                  {{"far_at_distance", p.distanceFarAt},
                   {"far_at_radius_px", p.radiusFarAt},
                   {"far_at_error_px", p.errorFarAt},
                   {"view_sets", p.viewSets},
                   {"sigmas", p.sigmas},
                   {"crossfade_frames", p.crossfades}}}};
    if (p.width) plan["size"] = {*p.width, *p.height};
    if (p.entityCap) plan["entity_cap"] = *p.entityCap;
    return {
        {"voxtier_bench", 1},
        {"modes", {"near_vulkan", "near_reference", "far", "hybrid"}},
        {"ground_truth",
         "near_vulkan: every entity drawn by the Vulkan near tier, same frame; errors of the "
         "other modes are measured against it (near_reference must differ in 0 pixels)"},
        {"plan", plan},
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
// Plots (gnuplot).

std::string shellQuote(const std::string& s) {
    std::string q = "'";
    for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
    return q + "'";
}

/// Whitespace-separated data file; strings have no spaces (the plots label with titles).
struct DataFile {
    std::string name;
    std::ostringstream text;
};

const char* kModes[] = {"near_vulkan", "near_reference", "far", "hybrid"};
const char* kModeColor[] = {"#1f77b4", "#9467bd", "#ff7f0e", "#2ca02c"};

struct PlotSet {
    std::vector<std::string> pngs;
    std::string note; ///< why plots are missing, if they are
};

PlotSet drawPlots(const SuiteResults& r, const fs::path& dir) {
    PlotSet out;
    if (std::system("command -v gnuplot >/dev/null 2>&1") != 0) {
        out.note = "gnuplot was not found on PATH (install gnuplot-nox; tools/setup.sh does), so "
                   "no plots were drawn; "
                   "the tables and results.csv hold every number.";
        return out;
    }
    const std::string first = r.rows.empty() ? "" : r.rows.front().scene;
    std::vector<std::pair<std::string, std::string>> files; // name, text
    std::ostringstream gp;
    gp << "set terminal pngcairo size 1400,620 font ',10' noenhanced\n"
          "set grid\nset key outside right top\n";

    // Speed against error: sweep points per family, the modes as single points, the Pareto front.
    std::vector<const Measurement*> pts;
    for (const Measurement& m : r.rows)
        if (m.scene == first && (m.group == "modes" || (m.group == "sweep" && m.hasError)))
            pts.push_back(&m);
    if (!pts.empty()) {
        static const char* kColors[] = {"#1f77b4", "#ff7f0e", "#2ca02c", "#d62728",
                                        "#9467bd", "#8c564b", "#e377c2", "#7f7f7f",
                                        "#bcbd22", "#17becf", "#000000", "#aec7e8"};
        std::map<std::string, std::vector<const Measurement*>> fam;
        for (const Measurement* m : pts)
            fam[m->group == "modes" ? "mode " + m->mode : m->family].push_back(m);
        std::string plotsA, plotsB;
        int k = 0;
        for (auto& [name, list] : fam) {
            std::sort(list.begin(), list.end(),
                      [](auto* a, auto* b) { return a->param < b->param; });
            std::ostringstream d;
            for (const Measurement* m : list)
                d << 100.0 * mismatchOf(*m) << " " << displacementOf(*m) << " " << m->totalMs
                  << "\n";
            const std::string file = "speed_error_" + std::to_string(k++) + ".dat";
            files.push_back({file, d.str()});
            const bool single = name.rfind("mode ", 0) == 0;
            const std::string color = std::string(" lc rgb '") + kColors[(k - 1) % 12] + "'";
            const std::string style =
                (single
                     ? "with points pt " + std::to_string(5 + 2 * (k % 4)) + " ps 2.2"
                     : "with linespoints pt " + std::to_string(5 + 2 * (k % 4)) + " ps 1.1 lw 2") +
                color;
            plotsA += (plotsA.empty() ? "" : ", ") + std::string("'") + file + "' using 1:3 " +
                      style + " title '" + name + "'";
            plotsB += (plotsB.empty() ? "" : ", ") + std::string("'") + file + "' using 2:3 " +
                      style + " title '" + name + "'";
        }
        for (int which = 0; which < 2; ++which) {
            auto front = paretoFront(pts, which == 0 ? mismatchOf : displacementOf);
            // Along increasing error (decreasing time), drawn as the staircase bounding what was
            // reached.
            std::reverse(front.begin(), front.end());
            std::ostringstream d;
            for (std::size_t i : front)
                d << (which == 0 ? 100.0 * mismatchOf(*pts[i]) : displacementOf(*pts[i])) << " "
                  << pts[i]->totalMs << "\n";
            const std::string file = which == 0 ? "pareto_mismatch.dat" : "pareto_displacement.dat";
            files.push_back({file, d.str()});
            (which == 0 ? plotsA : plotsB) +=
                ", '" + file +
                "' using 1:2 with steps lw 3 lc rgb '#555555' dt 2 title 'Pareto front', '" + file +
                "' using 1:2 with points pt 6 ps 2.6 lw 2 lc rgb '#000000' notitle";
        }
        gp << "set terminal pngcairo size 1400,760 font ',10' noenhanced\n"
           << "set output 'speed_error.png'\nset multiplot layout 1,2 title '" << first
           << ": frame ms against error (each point: median frame ms, mean over path frames)'\n"
              "set logscale y\nset xlabel ''\nset title 'x: mean per-entity footprint mismatch "
              "(%)'\n"
              "set ylabel 'frame ms (log)'\n"
              "set key outside bottom center horizontal maxrows 3 font ',9'\n"
           << "plot " << plotsA << "\n"
           << "set title 'x: worst silhouette displacement of a far entity drawn alone (virtual "
              "pixels)'\n"
           << "plot " << plotsB << "\nunset multiplot\nunset logscale\nunset title\n"
           << "set terminal pngcairo size 1400,620 font ',10' noenhanced\nset key default\n";
        out.pngs.push_back("speed_error.png");
    }

    // Scaling curves.
    auto curve = [&](const std::string& group, const std::string& file, const std::string& xlabel,
                     bool logx, const std::string& title) {
        std::string plots, plotsTier, plotsUnit;
        bool any = false;
        for (int mi = 0; mi < 4; ++mi) {
            std::vector<const Measurement*> list;
            for (const Measurement& m : r.rows)
                if (m.group == group && m.mode == kModes[mi]) list.push_back(&m);
            if (list.empty()) continue;
            any = true;
            std::sort(list.begin(), list.end(),
                      [](auto* a, auto* b) { return a->param < b->param; });
            std::ostringstream d;
            for (const Measurement* m : list)
                d << m->param << " " << m->totalMs << " " << m->nearMs << " " << m->fragments << " "
                  << m->blitMs << " " << m->blitPixels << " " << m->coldBakeMs << " "
                  << m->voxelSteps << "\n";
            const std::string dat = group + "_" + kModes[mi] + ".dat";
            files.push_back({dat, d.str()});
            plots += (plots.empty() ? "" : ", ") + std::string("'") + dat +
                     "' using 1:2 with linespoints pt 7 lw 2 lc rgb '" + kModeColor[mi] +
                     "' title '" + kModes[mi] + " frame'";
            // Right panel: each tier's time against the work it does.
            // Cost per unit of work: per shaded fragment (near), per footprint pixel (far blit).
            if (std::string(kModes[mi]) == "near_vulkan" ||
                std::string(kModes[mi]) == "near_reference")
                plotsUnit += (plotsUnit.empty() ? "" : ", ") + std::string("'") + dat +
                             "' using 1:($3*1e6/$4) with linespoints pt 7 lw 2 lc rgb '" +
                             kModeColor[mi] + "' title '" + kModes[mi] +
                             ": ns per shaded fragment'";
            if (std::string(kModes[mi]) == "far")
                plotsUnit += (plotsUnit.empty() ? "" : ", ") + std::string("'") + dat +
                             "' using 1:($5*1e6/$6) with linespoints pt 5 lw 2 lc rgb '" +
                             kModeColor[mi] + "' title 'far: ns per footprint pixel (blit)'";
            if (std::string(kModes[mi]) == "near_vulkan" ||
                std::string(kModes[mi]) == "near_reference")
                plotsTier += (plotsTier.empty() ? "" : ", ") + std::string("'") + dat +
                             "' using 4:3 with linespoints pt 7 lw 2 lc rgb '" + kModeColor[mi] +
                             "' title '" + kModes[mi] + ": near ms vs shaded fragments'";
            if (std::string(kModes[mi]) == "far") {
                plotsTier += (plotsTier.empty() ? "" : ", ") + std::string("'") + dat +
                             "' using 6:5 with linespoints pt 5 lw 2 lc rgb '" + kModeColor[mi] +
                             "' title 'far: blit ms vs footprint pixels'";
                if (group == "scaling_size")
                    plots += ", '" + dat +
                             "' using 1:7 with linespoints pt 4 dt 2 lw 1.5 lc rgb '" +
                             kModeColor[mi] + "' title 'far: cold bakes ms (once)'";
            }
        }
        if (!any) return;
        gp << "set output '" << file << "'\nset multiplot layout 1,2 title '" << title << "'\n"
           << (logx ? "set logscale x\n" : "set logscale x 2\n") << "set logscale y\nset xlabel '"
           << xlabel
           << "'\nset ylabel 'ms (log)'\nset key inside left top font ',8' box opaque\nplot "
           << plots << "\n";
        if (logx)
            gp << "set logscale x\nset xlabel 'work per frame: shaded fragments (near) / footprint "
                  "pixels (far blit)'\n"
               << "set ylabel 'tier ms (log)'\nplot " << plotsTier << "\n";
        else
            gp << "set xlabel '" << xlabel << "'\nset ylabel 'ns per unit of work (log)'\nplot "
               << plotsUnit << "\n";
        gp << "unset multiplot\nunset logscale\n";
        out.pngs.push_back(file);
    };
    curve("scaling_entities", "scaling_entities.png", "entities (log)", true,
          first + ": frame ms against entity count, per mode (one frame, camera at t = 0)");
    curve("scaling_size", "scaling_size.png",
          "model side in voxels (side x side x side/2, same size in metres)", false,
          first + ": frame ms against model size, per mode (one frame, camera at t = 0)");

    for (const auto& [name, text] : files) writeFile(dir / name, text);
    writeFile(dir / "plots.gp", gp.str());
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
// report.md

const Measurement* find(const SuiteResults& r, const std::string& group, const std::string& scene,
                        const std::string& mode) {
    for (const Measurement& m : r.rows)
        if (m.group == group && m.scene == scene && m.mode == mode) return &m;
    return nullptr;
}

std::string entitiesCell(const Measurement& m) {
    std::string s = num(m.nearDrawn, 0) + " / " + num(m.farDrawn, 0);
    if (m.fading >= 0.5) s += " (" + num(m.fading, 0) + " fading)";
    return s;
}

std::string overOne(const Measurement& m) {
    return m.farAloneEntities > 0 ? num(m.farOverOneCell, 1) + " of " + num(m.farAloneEntities, 0)
                                  : "–";
}

/// mean mismatch (coverage only) | worst mismatch | worst far displacement | far entities over 1
/// vpx | RMSE | PSNR
std::string errorCells(const Measurement& m) {
    if (!m.hasError) return "(truth) | | | | | ";
    return pct(m.mismatchMean) + " (" + pct(m.coverageMismatchMean) + ") | " +
           pct(m.mismatchWorst) + " | " + num(m.displacementWorstPx, 1) + " px (" +
           num(m.displacementWorstCells, 2) + ") | " + overOne(m) + " | " + num(m.rmseMean, 4) +
           " | " + num(m.psnrMin, 1);
}
const char* kErrorHeader =
    "mean mismatch (coverage only) | worst mismatch | worst far displacement alone (virtual px) | "
    "far entities displaced > 1 virtual px (per frame) | RMSE | min PSNR dB";
const char* kErrorAlign = "---:|---:|---:|---:|---:|---:";

std::string speedupCell(const Measurement& m) {
    return m.speedup > 0 ? num(m.speedup, 1) + "×" : "–";
}

void modesTable(std::ostringstream& md, const SuiteResults& r, const std::string& scene) {
    md << "| mode | near / far entities | frame ms | worst frame ms | speed-up vs all-near "
          "(Vulkan) | "
       << kErrorHeader << " |\n|---|---|---:|---:|---:|" << kErrorAlign << "|\n";
    for (const char* mode : kModes)
        if (const Measurement* m = find(r, "modes", scene, mode))
            md << "| " << mode << " | " << entitiesCell(*m) << " | " << num(m->totalMs) << " | "
               << num(m->worstFrameMs) << " | " << speedupCell(*m) << " | " << errorCells(*m)
               << " |\n";
}

} // namespace

std::vector<std::size_t> paretoFront(const std::vector<const Measurement*>& rows,
                                     double (*error)(const Measurement&)) {
    std::vector<std::size_t> front;
    for (std::size_t i = 0; i < rows.size(); ++i) {
        bool dominated = false;
        for (std::size_t j = 0; j < rows.size() && !dominated; ++j) {
            if (i == j) continue;
            const double ti = rows[i]->totalMs, tj = rows[j]->totalMs, ei = error(*rows[i]),
                         ej = error(*rows[j]);
            dominated = tj <= ti && ej <= ei && (tj < ti || ej < ei);
        }
        if (!dominated) front.push_back(i);
    }
    std::sort(front.begin(), front.end(),
              [&](std::size_t a, std::size_t b) { return rows[a]->totalMs < rows[b]->totalMs; });
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
    auto hasPlot = [&](const std::string& p) {
        return std::find(plots.pngs.begin(), plots.pngs.end(), p) != plots.pngs.end();
    };

    std::ostringstream md;
    const Plan& p = r.plan;
    const std::time_t now = std::time(nullptr);
    char date[64];
    std::strftime(date, sizeof date, "%Y-%m-%d %H:%M UTC", std::gmtime(&now));
    md << "# voxtier bench (" << p.preset << ")\n\n"
       << date << " · " << num(r.wallSeconds, 0) << " s · " << r.cpu << ", " << r.threads
       << " hardware threads · Vulkan: " << r.vulkanDevice << "\n\n"
       << "**How to read this.** Each configuration (a scene, a mode, selector settings) is drawn "
          "by its own "
          "renderer; the configurations of a scene run interleaved frame by frame in one process, "
          "so ratios see the "
          "same machine load. Per sampled path frame: "
       << p.warmup << " warm-up pass (cold bakes, pipeline compiles), then " << p.repeats
       << " timed passes; *frame ms* is the median over the passes, averaged over " << p.pathFrames
       << " path frame(s) (scaling points: one frame, " << p.scalingRepeats
       << " timed pass(es)). "
          "**Ground truth** for every error is the all-near image of the same frame drawn by the "
          "Vulkan near tier "
          "(`near_vulkan`); the CPU reference (`near_reference`) draws the same image by contract, "
          "and its "
          "*differing pixels* column shows it did. *Mismatch* is the per-entity footprint mismatch "
          "fraction "
          "(pixels owned by the entity in only one image, or with a different colour, over the "
          "union), averaged over "
          "the entities drawn (what the viewer sees, occlusion included); *displacement* is the "
          "far tier's own "
          "silhouette error: every entity the far tier drew is drawn alone by both tiers (CPU "
          "reference for the near "
          "side, identical to Vulkan by contract) and the largest distance from a pixel of one "
          "silhouette to the other "
          "silhouette is taken, in screen pixels and in virtual pixels (÷ the on-screen size of "
          "one lattice cell, at "
          "least 1 px). The machine is shared: read the ratios, not the last digit.\n\n";

    // The headline: the first scene's hybrid against all-near.
    const std::string first = r.rows.empty() ? "" : r.rows.front().scene;
    const Measurement* hyb = find(r, "modes", first, "hybrid");
    const Measurement* nvk = find(r, "modes", first, "near_vulkan");
    if (hyb && nvk) {
        md << "## " << first << ": hybrid against all-near\n\n"
           << "Hybrid (" << hyb->selector << "): **" << num(hyb->totalMs) << " ms** against **"
           << num(nvk->totalMs) << " ms** all-near on Vulkan: **" << speedupCell(*hyb)
           << "**, with " << num(hyb->nearDrawn, 0) << " near and " << num(hyb->farDrawn, 0)
           << " far entities; error " << pct(hyb->mismatchMean) << " mean / "
           << pct(hyb->mismatchWorst)
           << " worst footprint mismatch, worst far silhouette displacement "
           << num(hyb->displacementWorstPx, 1) << " px (" << num(hyb->displacementWorstCells, 2)
           << " virtual px).\n\n";
        // The goal of issue 7, the best measured error-selector setting that keeps the error
        // budget, and the fastest measured setting with what it costs.
        const Measurement* best = nullptr;
        const Measurement* fastest = nullptr;
        for (const Measurement& m : r.rows) {
            if (m.scene != first || (m.group != "modes" && m.group != "sweep") || !m.hasError ||
                m.mode == "near_reference")
                continue;
            if (m.mode == "hybrid" && isErrorSelector(m) && m.mismatchMean <= 0.02 &&
                m.farOverOneCell == 0 && (!best || m.speedup > best->speedup))
                best = &m;
            if (!fastest || m.speedup > fastest->speedup) fastest = &m;
        }
        md << "| goal | hybrid as configured | best error-selector setting within the error budget "
              "| fastest measured "
              "setting |\n|---|---|---|---|\n";
        auto row = [&](const char* goal, std::function<std::string(const Measurement&)> f) {
            md << "| " << goal << " | " << f(*hyb) << " | " << (best ? f(*best) : "none measured")
               << " | " << (fastest ? f(*fastest) : "–") << " |\n";
        };
        row("setting", [](const Measurement& m) {
            return m.mode == "far"     ? std::string("all far")
                   : m.setting.empty() ? m.selector
                                       : m.setting;
        });
        row("speed-up ≥ 10×",
            [](const Measurement& m) { return speedupCell(m) + (m.speedup >= 10 ? " ✓" : " ✗"); });
        row("mean footprint mismatch ≤ 2 % (coverage only)", [](const Measurement& m) {
            return pct(m.mismatchMean) + " (" + pct(m.coverageMismatchMean) + ")" +
                   (m.mismatchMean <= 0.02 ? " ✓" : " ✗");
        });
        row("no far entity displaced > 1 virtual px", [](const Measurement& m) {
            return "worst " + num(m.displacementWorstCells, 2) + "; " + overOne(m) + " per frame" +
                   (m.farOverOneCell == 0 ? " ✓" : " ✗");
        });
        row("near fragment share", [](const Measurement& m) {
            return m.baselineFragments > 0 ? pct(m.fragments / m.baselineFragments, 1)
                                           : std::string("–");
        });
        md << "\n*Near fragment share*: fragments the hybrid frame still shades on Vulkan over "
              "those of the all-near "
              "frame. Near costs per shaded fragment, so 1 / share bounds the speed-up whatever "
              "the far tier costs.\n\n";
    }

    md << "## Modes, per scene\n\n";
    std::set<std::string> seen;
    for (const Measurement& m : r.rows) {
        if (m.group != "modes" || !seen.insert(m.scene).second) continue;
        md << "### " << m.scene << "\n\n";
        modesTable(md, r, m.scene);
        if (const Measurement* ref = find(r, "modes", m.scene, "near_reference"))
            md << "\nnear_reference against near_vulkan: " << num(ref->differingPixels, 0)
               << " differing pixels per frame (colour, depth or id).\n";
        md << "\n";
    }

    md << "## Where the time goes: one hybrid frame\n\n"
          "The hybrid frame's steps (FrameStats, medians, mean over the path frames). *near draw* "
          "is record + submit + "
          "wait of the one instanced Vulkan draw; *near readback* copies the colour, id and depth "
          "targets to host memory; "
          "*far lookup + bake* finds every snapshot the far sprites need (warm cache: no "
          "bakes).\n\n"
          "| scene | setup | select | near upload | near draw | near readback | far lookup + bake "
          "| far blit | other | total |\n"
          "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n";
    for (const std::string& scene : seen)
        if (const Measurement* h = find(r, "modes", scene, "hybrid")) {
            const double other = h->totalMs - h->setupMs - h->selectMs - h->nearMs - h->farMs;
            const double nearOther =
                h->nearMs - h->nearUploadMs - h->nearDrawMs - h->nearReadbackMs;
            md << "| " << scene << " | " << num(h->setupMs) << " | " << num(h->selectMs) << " | "
               << num(h->nearUploadMs) << " | " << num(h->nearDrawMs) << " | "
               << num(h->nearReadbackMs) << " | " << num(h->bakeMs) << " | " << num(h->blitMs)
               << " | " << num(other + nearOther) << " | " << num(h->totalMs) << " |\n";
        }
    md << "\n";

    md << "## Throughput\n\n"
          "*rays/s*: Embree rays of the cold bakes (first warm-up pass) over their wall time; "
          "*voxel steps/s*: DDA voxel "
          "reads of the near kernel over the near draw time (Vulkan: counted by the step-counting "
          "shader in an extra, "
          "untimed frame; reference: counted in every frame); *blit px/s*: footprint pixels the "
          "blit evaluated over the "
          "blit time, next to a `memcpy` of the same bytes ("
       << num(12, 0)
       << " B per pixel: colour, depth, id) split "
          "over the TBB workers like the blit and timed in the same run — the bandwidth limit. "
          "Large-block memcpy: "
       << num(r.memcpyGBps, 1)
       << " GB/s.\n\n"
          "| scene | mode | cold bakes | cold bake ms | rays/s | voxel steps/s | blit Mpx/s | "
          "memcpy Mpx/s | blit / memcpy | cache MB |\n"
          "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|\n";
    for (const Measurement& m : r.rows) {
        if (m.group != "modes") continue;
        md << "| " << m.scene << " | " << m.mode << " | " << num(m.coldBakes, 0) << " | "
           << num(m.coldBakeMs, 1) << " | " << (m.raysPerS > 0 ? mega(m.raysPerS) + " M" : "–")
           << " | " << (m.voxelStepsPerS > 0 ? mega(m.voxelStepsPerS) + " M" : "–") << " | "
           << (m.blitPixelsPerS > 0 ? mega(m.blitPixelsPerS) : "–") << " | "
           << (m.memcpyPixelsPerS > 0 ? mega(m.memcpyPixelsPerS) : "–") << " | "
           << (m.memcpyPixelsPerS > 0 ? pct(m.blitPixelsPerS / m.memcpyPixelsPerS, 1) : "–")
           << " | " << num(m.cacheBytes / 1048576.0, 2) << " |\n";
    }
    md << "\n";

    // Sweeps.
    std::vector<const Measurement*> sweep;
    for (const Measurement& m : r.rows)
        if (m.group == "sweep" || (m.group == "modes" && m.scene == first)) sweep.push_back(&m);
    if (std::any_of(sweep.begin(), sweep.end(), [](auto* m) { return m->group == "sweep"; })) {
        const auto front = paretoFront(sweep, mismatchOf);
        std::set<const Measurement*> onFront;
        for (std::size_t i : front) onFront.insert(sweep[i]);
        md << "## Speed against error: sweeps on " << first << "\n\n"
           << "One change at a time from the scene's selector (" << (hyb ? hyb->selector : "")
           << "), hybrid mode, same "
              "path frames as above; *P* marks the Pareto front (no other configuration is both "
              "faster and closer to the "
              "truth on mean mismatch). Speed-ups are against all-near on Vulkan at the same "
              "sigma, measured in the same run.\n\n";
        if (hasPlot("speed_error.png")) md << "![frame ms against error](speed_error.png)\n\n";
        md << "| family | setting | near / far | frame ms | speed-up | near fragment share | "
           << kErrorHeader << " | P |\n|---|---|---|---:|---:|---:|" << kErrorAlign << "|---|\n";
        for (const Measurement* m : sweep)
            md << "| " << (m->group == "modes" ? "mode" : m->family) << " | "
               << (m->setting.empty() ? m->mode : m->setting) << " | " << entitiesCell(*m) << " | "
               << num(m->totalMs) << " | " << speedupCell(*m) << " | "
               << (m->baselineFragments > 0 && m->mode != "near_reference"
                       ? pct(m->fragments / m->baselineFragments, 1)
                       : "–")
               << " | " << errorCells(*m) << " | " << (onFront.count(m) ? "P" : "") << " |\n";
        md << "\n";
    }

    // Scaling.
    auto scalingTable = [&](const std::string& group, const std::string& title,
                            const std::string& png, const char* what) {
        std::vector<const Measurement*> rows;
        for (const Measurement& m : r.rows)
            if (m.group == group) rows.push_back(&m);
        if (rows.empty()) return;
        md << "## " << title << "\n\n";
        if (hasPlot(png)) md << "![" << title << "](" << png << ")\n\n";
        md << "| " << what
           << " | mode | near / far | frame ms | speed-up | near ms | near fragments | voxel steps "
              "| far blit ms "
              "| footprint px | cold bake ms | mean mismatch "
              "|\n|---|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n";
        for (const Measurement* m : rows)
            md << "| " << m->setting << " | " << m->mode << " | " << entitiesCell(*m) << " | "
               << num(m->totalMs) << " | " << speedupCell(*m) << " | " << num(m->nearMs) << " | "
               << num(m->fragments, 0) << " | " << num(m->voxelSteps, 0) << " | " << num(m->blitMs)
               << " | " << num(m->blitPixels, 0) << " | " << num(m->coldBakeMs, 1) << " | "
               << (m->hasError ? pct(m->mismatchMean) : "(truth)") << " |\n";
        md << "\n";
    };
    scalingTable("scaling_entities", "Scaling: entity count", "scaling_entities.png", "entities");
    scalingTable("scaling_size", "Scaling: model size", "scaling_size.png", "model");

    md << "## Notes\n\n";
    if (!plots.note.empty()) md << "- Plots: " << plots.note << "\n";
    for (const std::string& n : r.notes) md << "- " << n << "\n";
    md << "- Files: `results.csv` (one row per configuration), `results.json` (the same with "
          "per-frame detail)";
    for (const std::string& png : plots.pngs) md << ", `" << png << "`";
    md << ".\n";
    writeFile(dir / "report.md", md.str());
    written.push_back((dir / "report.md").string());
    return written;
}

} // namespace voxtier::bench
