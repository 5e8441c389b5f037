// The preset table and the overrides of `voxtier bench` (apps/bench/presets.hpp).
#include "apps/bench/presets.hpp"

#include "apps/bench/harness.hpp"
#include "core/error.hpp"

#include <algorithm>
#include <cstdio>
#include <stdexcept>

namespace voxtier::bench {

namespace {

// One row per preset; a field a row leaves out keeps Preset's default (an empty list: that
// sweep or curve is not run).
const Preset kPresets[] = {
    {.name = "full",
     .repeats = 7,
     .pathFrames = 6,
     .motionFrames = 48,
     .motionWarmup = 6,
     .distanceFarAt = {10, 20, 40, 80},
     .radiusFarAt = {32, 16, 8, 4},
     .errorFarAt = {4, 2, 1, 0.5, 0.25},
     .viewSets = {26, 98, 218},
     .crossfades = {0, 4, 8},
     .budgets = {0.25, 0.5, 1, 2, 4},
     .snapshotScales = {1, 2, 3, 4},
     .ladderCaps = {4, 16, 64},
     .sigmas = {0.5, 1, 2},
     .entityCounts = {10, 100, 300, 1000, 3000, 10000, 30000, 100000},
     .modelSides = {16, 32, 64, 128},
     .sizeEntities = 500,
     .scalingRepeats = 5},
    {.name = "quick",
     .repeats = 3,
     .pathFrames = 2,
     .motionFrames = 16,
     .motionWarmup = 4,
     .distanceFarAt = {15, 40},
     .radiusFarAt = {24, 8},
     .errorFarAt = {2, 0.5, 0.25},
     .viewSets = {26, 98},
     .crossfades = {0, 8},
     .budgets = {0.25, 0.5, 1, 2, 4},
     .snapshotScales = {1, 3},
     .ladderCaps = {4, 16},
     .entityCounts = {10, 100, 1000, 10000},
     .modelSides = {16, 32, 64, 128},
     .sizeEntities = 300,
     .scalingRepeats = 1},
    {.name = "smoke",
     .testOnly = true,
     .repeats = 1,
     .pathFrames = 1,
     .motionFrames = 3,
     .motionWarmup = 1,
     .width = 240,
     .height = 136,
     .entityCap = 24,
     .errorFarAt = {1},
     .budgets = {1},
     .snapshotScales = {1},
     .entityCounts = {4, 12},
     .modelSides = {16, 32},
     .sizeEntities = 6,
     .scalingRepeats = 1},
};

const CountOverride kCountOverrides[] = {
    {"--repeats", &SuiteOptions::repeats, &Preset::repeats, 1, "", "Timed passes per path frame"},
    {"--warmup", &SuiteOptions::warmup, &Preset::warmup, 1,
     "the cold bakes are measured in the first warm-up pass",
     "Untimed passes first; cold bakes are measured in the first"},
    {"--frames", &SuiteOptions::pathFrames, &Preset::pathFrames, 1, "",
     "Path frames sampled per scene"},
    {"--motion-frames", &SuiteOptions::motionFrames, &Preset::motionFrames, 2, "",
     "Consecutive path frames of the in-motion run, cold start included; an animated crowd "
     "fills its snapshot cache over one animation cycle"},
    {"--motion-warmup", &SuiteOptions::motionWarmup, &Preset::motionWarmup, 1, "",
     "Of those, the first frames reported as the cold start, not timed in motion"},
};

const ListOverride kListOverrides[] = {
    {"--entity-counts", &SuiteOptions::entityCounts, &Preset::entityCounts, 1, 100000,
     "Entity counts of the scaling curve"},
    {"--model-sides", &SuiteOptions::modelSides, &Preset::modelSides, 8, Limits::kMaxModelDim,
     "Tank sides (voxels) of the model-size curve"},
    {"--snapshot-scales", &SuiteOptions::snapshotScales, &Preset::snapshotScales, 1,
     kMaxSnapshotScale,
     "Snapshot scales of the error_budget sweep, each run at every budget: the far tier's "
     "snapshots at that multiple of the sprite's sigma"},
};

/// "(default: A, --quick B)" from each offered preset's text of a figure (lists: "A; --quick B").
template <class Text> std::string defaultsOf(Text text, const std::string& between) {
    std::string out;
    for (const Preset& p : kPresets)
        if (!p.testOnly)
            out += (out.empty() ? "(default: " : between + " --" + p.name + " ") + text(p);
    return out + ")";
}

} // namespace

FrameOptions benchFrameOptions() {
    FrameOptions o;
    o.farBackend = FarBackend::Cpu;
    return o;
}

std::span<const Preset> presets() {
    return kPresets;
}

const Preset& presetNamed(const std::string& name) {
    for (const Preset& p : kPresets)
        if (p.name == name) return p;
    throw std::logic_error("bench: no preset named '" + name + "'");
}

std::span<const CountOverride> countOverrides() {
    return kCountOverrides;
}

std::span<const ListOverride> listOverrides() {
    return kListOverrides;
}

std::string presetDefaults(int Preset::*field) {
    return defaultsOf([&](const Preset& p) { return std::to_string(p.*field); }, ",");
}

std::string presetDefaults(std::vector<int> Preset::*field) {
    return defaultsOf(
        [&](const Preset& p) {
            std::string list;
            for (int v : p.*field) list += (list.empty() ? "" : ",") + std::to_string(v);
            return list;
        },
        ";");
}

Plan makePlan(const SuiteOptions& o) {
    Plan plan;
    static_cast<Preset&>(plan) = presetNamed(o.preset);
    plan.frame = o.frame;
    // The same bounds as the command line's (cmd_bench.cpp), for other callers.
    if (o.budgetVpx && !(*o.budgetVpx >= 0.01 && *o.budgetVpx <= 64.0))
        throw InputError("", "--budget", "must be in [0.01, 64] virtual pixels");
    plan.budgetVpx = o.budgetVpx;
    for (const CountOverride& c : kCountOverrides) {
        const std::optional<int>& given = o.*c.given;
        if (!given) continue;
        if (*given < c.least)
            throw InputError("", c.flag,
                             "must be >= " + std::to_string(c.least) +
                                 (*c.why ? std::string(" (") + c.why + ")" : std::string()));
        plan.*c.field = *given;
    }
    if (plan.motionWarmup >= plan.motionFrames)
        throw InputError("", "--motion-warmup",
                         "must be less than --motion-frames (" + std::to_string(plan.motionFrames) +
                             "): no frame would be timed in motion");
    for (const ListOverride& l : kListOverrides) {
        if ((o.*l.given).empty()) continue;
        std::vector<int>& list = plan.*l.field;
        list.clear();
        // A value named twice would be measured once and drawn twice.
        for (int v : cli::parseList<int>(o.*l.given, l.flag, l.lo, l.hi))
            if (std::find(list.begin(), list.end(), v) == list.end()) list.push_back(v);
    }
    if (!o.size.empty()) {
        int w = 0, h = 0;
        char tail = 0;
        if (std::sscanf(o.size.c_str(), "%dx%d%c", &w, &h, &tail) != 2 || w < 1 || h < 1 ||
            w > Limits::kMaxImageDim || h > Limits::kMaxImageDim)
            throw InputError("", "--size",
                             "expected WxH with integers 1.." +
                                 std::to_string(Limits::kMaxImageDim) + ", got '" + o.size + "'");
        plan.width = w, plan.height = h;
    }
    plan.sweeps = plan.sweeps && o.sweeps;
    plan.scaling = plan.scaling && o.scaling;
    return plan;
}

} // namespace voxtier::bench
