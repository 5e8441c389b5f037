// results.csv and results.json of `voxtier bench` (apps/bench/results.hpp).
#include "apps/bench/results.hpp"

#include "apps/bench/harness.hpp"
#include "core/file_write.hpp"

#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdio>
#include <functional>

namespace voxtier::bench {

namespace {

using cli::sig;
using nlohmann::json;

/// One column: its name in both files, how a row gives its value, and where a JSON row holds
/// it (every column is in the CSV).
struct Column {
    enum class In {
        Row,         ///< a field of the JSON row
        CsvOnly,     ///< the JSON row has it otherwise (its "frames" array)
        ErrorObject, ///< a field of the JSON row's "error" object (null for the truth)
    };
    std::string name;
    std::function<json(const Measurement&)> value;
    In in = In::Row;
};

template <class T> std::function<json(const Measurement&)> field(T Measurement::*f) {
    return [f](const Measurement& m) { return json(m.*f); };
}
template <class Part, class T>
std::function<json(const Measurement&)> field(Part Measurement::*part, T Part::*f) {
    return [part, f](const Measurement& m) { return json(m.*part.*f); };
}

std::vector<Column> columns() {
    using In = Column::In;
    using M = Measurement;
    std::vector<Column> c = {
        {"group", field(&M::group)},
        {"scene", field(&M::scene)},
        {"mode", [](const M& m) { return json(toString(m.mode)); }},
        {"family", field(&M::family)},
        {"setting", field(&M::setting)},
        {"param", field(&M::param)},
        {"selector", field(&M::selector)},
        {"truth", field(&M::truth)},
        {"frames", [](const M& m) { return json(m.frames.size()); }, In::CsvOnly},
    };
    // Every frame figure, by its own name (the path's frames combined as the table says).
    for (std::size_t i = 0; i < kFrameFigureCount; ++i)
        c.push_back({kFrameFigures[i].name, [i](const M& m) { return json(m.figures.values[i]); }});
    const std::vector<Column> bench = {
        {"visible", field(&M::visible)},
        {"worst_frame_ms", field(&M::worstFrameMs)},
        {"device_frame_ms", field(&M::deviceFrameMs)},
        {"all_near_vulkan_ms", field(&M::allNearVulkanMs)},
        {"speedup_vs_all_near_vulkan", field(&M::speedupVsAllNearVulkan)},
        {"near_vulkan_fragment_ms", field(&M::nearVulkanFragmentMs)},
        {"speedup_vs_near_vulkan_fragment", field(&M::speedupVsNearVulkanFragment)},
        {"all_near_vulkan_fragments", field(&M::allNearVulkanFragments)},
        {"voxel_steps_per_s", field(&M::voxelStepsPerS)},
        {"blit_pixels_per_s", field(&M::blitPixelsPerS)},
        {"memcpy_pixels_per_s", field(&M::memcpyPixelsPerS)},
        {"in_motion_ms", field(&M::motion, &InMotion::ms)},
        {"in_motion_mean_ms", field(&M::motion, &InMotion::meanMs)},
        {"in_motion_p90_ms", field(&M::motion, &InMotion::p90Ms)},
        {"in_motion_worst_ms", field(&M::motion, &InMotion::worstMs)},
        {"in_motion_cold_ms", field(&M::motion, &InMotion::coldMs)},
        {"in_motion_all_near_vulkan_ms", field(&M::motion, &InMotion::allNearVulkanMs)},
        {"in_motion_speedup_vs_all_near_vulkan",
         field(&M::motion, &InMotion::speedupVsAllNearVulkan)},
        {"in_motion_all_near_reference_ms", field(&M::motion, &InMotion::allNearReferenceMs)},
        {"in_motion_speedup_vs_all_near_reference",
         field(&M::motion, &InMotion::speedupVsAllNearReference)},
        {"in_motion_fastest_exact_ms", field(&M::motion, &InMotion::fastestExactMs)},
        {"in_motion_speedup_vs_fastest_exact", field(&M::motion, &InMotion::speedupVsFastestExact)},
        {"near_backend", field(&M::nearBackend)},
        {"far_backend", field(&M::farBackend)},
        {"snapshot_scale", field(&M::snapshotScale)},
        {"in_motion_bakes_per_frame", field(&M::motion, &InMotion::bakes)},
        {"in_motion_bake_ms_per_frame", field(&M::motion, &InMotion::bakeMs)},
        {"in_motion_cache_bytes", field(&M::motion, &InMotion::cacheBytes)},
        {"in_motion_near_ms", field(&M::motion, &InMotion::nearMs)},
        {"in_motion_near_entities", field(&M::motion, &InMotion::nearEntities)},
        {"in_motion_far_entities", field(&M::motion, &InMotion::farEntities)},
        {"in_motion_psnr_min", field(&M::motion, &InMotion::psnrMin)},
        {"in_motion_differing_share", field(&M::motion, &InMotion::differingShare)},
        {"in_motion_psnr_min_differing_pixels",
         field(&M::motion, &InMotion::psnrMinDifferingPixels)},
        {"in_motion_psnr_min_far_entities", field(&M::motion, &InMotion::psnrMinFarEntities)},
        {"in_motion_predicted_worst_vpx", field(&M::motion, &InMotion::predictedWorstVpx)},
        {"cold_first_frame_ms", field(&M::cold, &Cold::firstFrameMs)},
        {"cold_bake_ms", field(&M::cold, &Cold::bakeMs)},
        {"cold_bakes", field(&M::cold, &Cold::bakes)},
        {"cold_rays", field(&M::cold, &Cold::rays)},
        {"rays_per_s", field(&M::cold, &Cold::raysPerS)},
        {"fastest_exact", field(&M::fastestExact)},
        {"fastest_exact_ms", field(&M::fastestExactMs)},
        {"speedup_vs_fastest_exact", field(&M::speedupVsFastestExact)},
        {"all_near_same_backend_fragments", field(&M::allNearSameBackendFragments)},
        {"in_motion_psnr_min_share", field(&M::motion, &InMotion::psnrMinShare)},
        {"image_pixels", field(&M::imagePixels)},
        {"has_error", field(&M::hasError)},
        {"mismatch_mean", field(&M::error, &PathError::mismatchMean), In::ErrorObject},
        {"mismatch_worst", field(&M::error, &PathError::mismatchWorst), In::ErrorObject},
        {"coverage_mismatch_mean", field(&M::error, &PathError::coverageMismatchMean),
         In::ErrorObject},
        {"far_mismatch_mean", field(&M::error, &PathError::farMismatchMean), In::ErrorObject},
        {"far_alone_mismatch_mean", field(&M::error, &PathError::farAloneMismatchMean),
         In::ErrorObject},
        {"far_displacement_worst_px", field(&M::error, &PathError::farDisplacementWorstPx),
         In::ErrorObject},
        {"far_displacement_worst_vpx", field(&M::error, &PathError::farDisplacementWorstVpx),
         In::ErrorObject},
        {"far_visible_displacement_worst_px",
         field(&M::error, &PathError::farVisibleDisplacementWorstPx), In::ErrorObject},
        {"far_alone_entities", field(&M::error, &PathError::farAloneEntities), In::ErrorObject},
        {"far_displaced_over_1_vpx", field(&M::error, &PathError::farDisplacedOver1Vpx),
         In::ErrorObject},
        {"rmse_mean", field(&M::error, &PathError::rmseMean), In::ErrorObject},
        {"psnr_min", field(&M::error, &PathError::psnrMin), In::ErrorObject},
        {"differing_pixels", field(&M::error, &PathError::differingPixels), In::ErrorObject},
        {"missing_entities", field(&M::error, &PathError::missingEntities), In::ErrorObject},
    };
    c.insert(c.end(), bench.begin(), bench.end());
    // Where an in-motion frame's time goes: each time figure's mean over the timed frames in
    // motion (InMotion::split), by its own name after "in_motion_mean_".
    for (std::size_t i = 0; i < kFrameFigureCount; ++i)
        if (kFrameFigures[i].unit == FigureUnit::Ms)
            c.push_back({std::string("in_motion_mean_") + kFrameFigures[i].name,
                         [i](const M& m) { return json(m.motion.split.values[i]); }});
    return c;
}

std::string csvField(const std::string& s) {
    if (s.find_first_of(",\"\n") == std::string::npos) return s;
    std::string q = "\"";
    for (char c : s) q += c == '"' ? std::string("\"\"") : std::string(1, c);
    return q + "\"";
}

std::string csvText(const json& v) {
    if (v.is_string()) return csvField(v.get<std::string>());
    if (v.is_boolean()) return v.get<bool>() ? "1" : "0";
    if (v.is_number_float()) return sig(v.get<double>());
    return v.is_null() ? "" : v.dump();
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
    for (std::size_t i = 0; i < kFrameFigureCount; ++i) {
        const FrameFigure& fig = kFrameFigures[i];
        const double v = f.median.values[i];
        fr[fig.name] = isWhole(fig.unit) ? json(std::int64_t(v)) : json(v);
    }
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
        if (c.in == Column::In::Row) row[c.name] = c.value(m);
        if (c.in == Column::In::ErrorObject) error[c.name] = c.value(m);
    }
    row["error"] = m.hasError ? error : json(nullptr);
    row["frames"] = json::array();
    for (const FrameRow& f : m.frames) row["frames"].push_back(frameJson(f));
    return row;
}

json planJson(const Plan& p) {
    json scales = json::array();
    for (int k : p.snapshotScales) scales.push_back(scaleName(k));
    json plan = {{"preset", p.name},
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
                   {"snapshot_scales", scales},
                   {"ladder_caps", p.ladderCaps},
                   {"view_sets", p.viewSets},
                   {"sigmas", p.sigmas},
                   {"crossfade_frames", p.crossfades}}}};
    if (p.width) plan["size"] = {*p.width, *p.height};
    if (p.entityCap) plan["entity_cap"] = *p.entityCap;
    if (p.budgetVpx) plan["budget_vpx"] = *p.budgetVpx;
    plan["near_rate"] = toString(p.frame.nearRate);
    plan["far_blit"] = toString(p.frame.farBlit.kernel);
    plan["far_backend"] = toString(p.frame.farBackend);
    plan["occlusion_cull"] = p.frame.occlusionCull;
    plan["early_depth_test"] = p.frame.earlyDepthTest;
    plan["cost_bound"] = p.frame.costAwareBakes;
    return plan;
}

} // namespace

std::vector<std::string> resultColumns() {
    std::vector<std::string> names;
    for (const Column& c : columns()) names.push_back(c.name);
    return names;
}

std::string resultsCsv(const SuiteResults& r) {
    const std::vector<Column> cols = columns();
    const auto line = [&](auto text) {
        std::string out;
        for (const Column& c : cols) out += (&c == &cols.front() ? "" : ",") + text(c);
        return out + "\n";
    };
    std::string out = line([](const Column& c) { return c.name; });
    for (const Measurement& m : r.rows)
        out += line([&](const Column& c) { return csvText(c.value(m)); });
    return out;
}

std::string resultsJson(const SuiteResults& r) {
    const std::vector<Column> cols = columns();
    json rows = json::array();
    for (const Measurement& m : r.rows) rows.push_back(rowJson(m, cols));
    json modes = json::array(), figures = json::array();
    for (const BenchModeInfo& mode : kBenchModes) modes.push_back(mode.name);
    for (const FrameFigure& f : kFrameFigures)
        figures.push_back({{"name", f.name},
                           {"unit", toString(f.unit)},
                           {"across_frames", toString(f.acrossFrames)}});
    const json doc = {
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
        {"notes", r.notes}};
    return doc.dump(1) + "\n";
}

std::vector<std::string> writeResults(const SuiteResults& r, const std::filesystem::path& dir) {
    const std::filesystem::path csv = dir / "results.csv", json = dir / "results.json";
    writeFileWhole(csv, resultsCsv(r));
    writeFileWhole(json, resultsJson(r));
    return {csv.string(), json.string()};
}

} // namespace voxtier::bench
