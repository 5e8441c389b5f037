// "Where the time goes" in the bench report (apps/bench/time_split.hpp).
#include "apps/bench/time_split.hpp"

#include "apps/bench/report_cells.hpp"
#include "compose/frame_figures.hpp"

#include <algorithm>
#include <iterator>
#include <string>
#include <vector>

namespace voxtier::bench {

namespace {

using nlohmann::json;
using namespace cells;

/// A column of the time split: a figure of kFrameFigures, and whether it is a part of the
/// tier column before it.
struct TimeColumn {
    std::size_t figure;
    bool part;
    bool tier = false; ///< a tier's whole time (either backend)
};

/// The time split's columns, from the figure table: the frame's time steps (its timeStep
/// lines), with each tier's whole time (near_ms, far_ms: either backend) before the steps named
/// after it ("near_…", "far_…"), which are parts of it. What no column holds is "other".
std::vector<TimeColumn> timeColumns() {
    const std::size_t tiers[] = {FigureId("near_ms").index, FigureId("far_ms").index};
    const auto tierPrefix = [](std::size_t tier) {
        const std::string name = kFrameFigures[tier].name; // "near_ms" -> "near_"
        return name.substr(0, name.size() - 2);
    };
    const auto partOf = [&](std::size_t i, std::size_t tier) {
        return std::string(kFrameFigures[i].name).starts_with(tierPrefix(tier));
    };
    std::vector<TimeColumn> cols;
    for (std::size_t i = 0; i < kFrameFigureCount; ++i)
        if (kFrameFigures[i].timeStep && std::none_of(std::begin(tiers), std::end(tiers),
                                                      [&](std::size_t t) { return partOf(i, t); }))
            cols.push_back({i, false});
    for (std::size_t tier : tiers) {
        cols.push_back({tier, false, true});
        for (std::size_t i = 0; i < kFrameFigureCount; ++i)
            if (kFrameFigures[i].timeStep && i != tier && partOf(i, tier))
                cols.push_back({i, true});
    }
    return cols;
}

json timeSplitHeadings() {
    json headings = json::array();
    for (const TimeColumn& c : timeColumns()) {
        const FrameFigure& f = kFrameFigures[c.figure];
        headings.push_back(f.words() + (c.tier ? " tier" : ""));
    }
    return headings;
}

/// Which figures of a measurement a split reads: the warm frame's (Measurement::figures), or the
/// means of its frames in motion (InMotion::split; none where it was not timed in motion).
using SplitOf = const Figures* (*)(const Measurement&);
const Figures* warmSplit(const Measurement& m) {
    return &m.figures;
}
const Figures* motionSplit(const Measurement& m) {
    return m.motion.ms > 0 ? &m.motion.split : nullptr;
}

/// Every mode's frame per scene, split by the time columns; "other" is the rest of frame_ms. Each
/// figure of the warm frame is its own median over the passes, so the columns can add up to a
/// little more than the total: "other" is then 0. In motion they are means, which add up.
json stepsContext(const SuiteResults& r, SplitOf splitOf) {
    const std::vector<TimeColumn> cols = timeColumns();
    json rows = json::array();
    for (const std::string& scene : sceneNames(r))
        for (const BenchModeInfo& mode : kBenchModes) {
            const Measurement* m = find(r, kModesGroup, scene, mode.mode);
            const Figures* f = m ? splitOf(*m) : nullptr;
            if (!f) continue;
            json steps = json::array();
            double other = (*f)["frame_ms"];
            for (const TimeColumn& c : cols) {
                steps.push_back(num(f->values[c.figure]));
                if (!c.part) other -= f->values[c.figure];
            }
            rows.push_back({{"scene", scene},
                            {"mode", mode.name},
                            {"steps", steps},
                            {"other", num(std::max(0.0, other))},
                            {"total", num((*f)["frame_ms"])}});
        }
    return rows;
}

/// The Vulkan frame's columns, from the table: the host's part of it that is no time step
/// (host_record_ms, host_wait_ms, host_readback_ms) and the device's own pass times (gpu_*).
/// Not the selection's parts (host_select_*_ms): they split a time step the CPU takes before the
/// Vulkan frame.
std::vector<std::size_t> deviceColumns() {
    std::vector<std::size_t> cols;
    for (std::size_t i = 0; i < kFrameFigureCount; ++i) {
        const std::string name = kFrameFigures[i].name;
        if ((name.starts_with("host_") && !name.starts_with("host_select_") &&
             !kFrameFigures[i].timeStep) ||
            name.starts_with("gpu_"))
            cols.push_back(i);
    }
    return cols;
}

/// A row per mode of each scene that drew a tier on Vulkan, split by deviceColumns().
json deviceContext(const SuiteResults& r, SplitOf splitOf) {
    const std::vector<std::size_t> cols = deviceColumns();
    json rows = json::array();
    for (const std::string& scene : sceneNames(r))
        for (const BenchModeInfo& mode : kBenchModes) {
            const Measurement* m = find(r, kModesGroup, scene, mode.mode);
            const Figures* f = m ? splitOf(*m) : nullptr;
            if (!f || ((*f)["near_on_vulkan"] <= 0 && (*f)["far_on_vulkan"] <= 0)) continue;
            json steps = json::array();
            for (const std::size_t c : cols) steps.push_back(num(f->values[c]));
            rows.push_back({{"scene", scene}, {"mode", mode.name}, {"steps", steps}});
        }
    return rows;
}

} // namespace

json timeSplitContext(const SuiteResults& r) {
    json deviceSteps = json::array();
    for (const std::size_t c : deviceColumns()) deviceSteps.push_back(kFrameFigures[c].name);
    return {{"time_steps", timeSplitHeadings()},
            {"time_split", stepsContext(r, warmSplit)},
            {"device_steps", deviceSteps},
            {"device_split", deviceContext(r, warmSplit)},
            {"motion_time_split", stepsContext(r, motionSplit)},
            {"motion_device_split", deviceContext(r, motionSplit)}};
}

} // namespace voxtier::bench
