// The bench's configurations and sets: which configurations a scene and the plan's sweeps and
// scaling points give (apps/bench/sets.hpp).
#include "apps/bench/sets.hpp"

#include "apps/bench/harness.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>
#include <stdexcept>
#include <tuple>

namespace voxtier::bench {

namespace {

/// Settings in words and configuration keys: six significant digits, as in the results.
std::string fmt(double v) {
    return cli::sig(v);
}

/// Adds a configuration; the truth of a truth configuration is itself.
int addConfig(Set& set, const Scene& scene, BenchMode mode, const std::string& name) {
    auto c = std::make_unique<Config>();
    c->name = name;
    c->mode = mode;
    c->scene = scene;
    c->isTruth = info(mode).isTruth;
    set.configs.push_back(std::move(c));
    return int(set.configs.size()) - 1;
}

Measurement label(const std::string& group, const std::string& scene, BenchMode mode,
                  const std::string& family = "", const std::string& setting = "",
                  double param = 0.0) {
    Measurement m;
    m.group = group;
    m.scene = scene;
    m.mode = mode;
    m.family = family;
    m.setting = setting;
    m.param = param;
    return m;
}

void linkTruths(Set& set) {
    // Each approximate configuration is compared with the near_vulkan configuration of the same
    // sigma (the sprites' lattice depends on it; nothing else in a scene copy differs).
    for (auto& c : set.configs) {
        if (c->isTruth) continue;
        for (std::size_t t = 0; t < set.configs.size(); ++t)
            if (set.configs[t]->isTruth &&
                set.configs[t]->scene.render.sigma == c->scene.render.sigma) {
                c->truth = int(t);
                break;
            }
    }
    // Truths render first in every frame, so their images exist when the others are compared.
    for (std::size_t i = 0; i < set.configs.size(); ++i)
        if (!set.configs[i]->isTruth)
            for (std::size_t j = i + 1; j < set.configs.size(); ++j)
                if (set.configs[j]->isTruth)
                    throw std::logic_error("bench: truth configurations must come first");
}

std::pair<std::vector<int>, std::vector<double>> pathSamples(const Scene& s, int count) {
    std::vector<int> frames;
    if (s.path && count > 1) {
        const int n = s.path->frameCount();
        const int k = std::min(count, n);
        for (int i = 0; i < k; ++i)
            frames.push_back(k == 1 ? 0 : int(std::lround(double(i) * (n - 1) / (k - 1))));
    } else {
        frames.push_back(0);
    }
    std::vector<double> times;
    for (int f : frames) times.push_back(s.path ? s.timeOfFrame(f) : 0.0);
    return {frames, times};
}

// ---------------------------------------------------------------------------------------------
// Scenes.

void applyOverrides(Scene& s, const Plan& plan, bool capEntities) {
    if (plan.width) s.camera.width = *plan.width, s.camera.height = *plan.height;
    if (plan.budgetVpx) {
        SelectorConfig c = defaultSelectorFor(SelectorMetric::ErrorBudget);
        c.budgetVpx = *plan.budgetVpx;
        c.viewSetSize = s.selector.viewSetSize;
        c.viewHysteresisDeg = s.selector.viewHysteresisDeg;
        c.crossfadeFrames = s.selector.crossfadeFrames;
        c.snapshotScale = s.selector.snapshotScale;
        s.selector = c;
    }
    if (capEntities && plan.entityCap && int(s.entities.size()) > *plan.entityCap)
        s.entities.resize(std::size_t(*plan.entityCap));
}

struct SweepPoint {
    std::string family, setting;
    double param = 0.0;
    SelectorConfig selector;
    double sigma = 1.0;
};

std::string configKey(const SelectorConfig& c, double sigma) {
    return std::string(toString(c.metric)) + "/" + fmt(c.nearAt) + "/" + fmt(c.farAt) + "/" +
           std::to_string(c.viewSetSize) + "/" + std::to_string(c.crossfadeFrames) + "/" +
           fmt(c.viewHysteresisDeg) + "/" + fmt(sigma) + "/" + fmt(c.budgetVpx) + "/" +
           std::to_string(c.ladderCap) + "/" + std::to_string(c.snapshotScale);
}

std::vector<SweepPoint> sweepPoints(const Plan& plan, const Scene& base) {
    std::vector<SweepPoint> pts;
    const SelectorConfig s0 = base.selector;
    const double sigma0 = base.render.sigma;
    auto farAt = [&](SelectorMetric metric, const std::vector<double>& values, double nearFactor) {
        for (double v : values) {
            SweepPoint p;
            p.family = std::string("far_at (") + toString(metric) + ")";
            p.selector = s0;
            p.selector.metric = metric;
            p.selector.farAt = v;
            p.selector.nearAt = v * nearFactor;
            p.sigma = sigma0;
            p.param = v;
            p.setting = std::string(toString(metric)) + " far_at=" + fmt(v) +
                        " near_at=" + fmt(v * nearFactor);
            pts.push_back(p);
        }
    };
    farAt(SelectorMetric::Distance, plan.distanceFarAt, 0.8);
    farAt(SelectorMetric::RadiusPx, plan.radiusFarAt, 1.5);
    farAt(SelectorMetric::ErrorPx, plan.errorFarAt, 2.0);
    // The error budget (issue 13): each budget with each snapshot scale (the speed–error
    // frontier, issue 29), then the ladder cap at the scene's budget.
    for (int k : plan.snapshotScales)
        for (double b : plan.budgets) {
            SweepPoint p{kBudgetFamily, "error_budget " + fmt(b) + " vpx, " + scaleName(k), b, s0,
                         sigma0};
            p.selector = defaultSelectorFor(SelectorMetric::ErrorBudget);
            p.selector.budgetVpx = b;
            p.selector.snapshotScale = k;
            pts.push_back(p);
        }
    for (int cap : plan.ladderCaps) {
        SweepPoint p{"ladder cap (error_budget)",
                     "error_budget 1 vpx, ladder cap " + std::to_string(cap), double(cap), s0,
                     sigma0};
        p.selector = defaultSelectorFor(SelectorMetric::ErrorBudget);
        p.selector.ladderCap = cap;
        pts.push_back(p);
    }
    for (int v : plan.viewSets) {
        SweepPoint p{"view set", std::to_string(v) + " views", double(v), s0, sigma0};
        p.selector.viewSetSize = v;
        pts.push_back(p);
    }
    for (double s : plan.sigmas) pts.push_back({"sigma", "sigma=" + fmt(s), s, s0, s});
    for (int n : plan.crossfades) {
        SweepPoint p{"cross-fade",
                     n ? "cross-fade " + std::to_string(n) + " frames" : "no cross-fade", double(n),
                     s0, sigma0};
        p.selector.crossfadeFrames = n;
        pts.push_back(p);
    }
    return pts;
}

} // namespace

Set modesSet(const SceneSource& src, const Plan& plan, bool withSweeps,
             std::vector<std::string>& notes) {
    Set set;
    const std::string name = sceneName(src.file);
    set.label = name;
    set.inMotion = true;
    Scene base = src.scene;
    applyOverrides(base, plan, /*capEntities=*/true);
    std::tie(set.frames, set.times) = pathSamples(base, plan.pathFrames);
    set.repeats = plan.repeats;
    if (!base.edits.empty())
        notes.push_back(name +
                        ": its scripted edits are not applied (`bench edits` measures edits).");
    const std::vector<SweepPoint> pts =
        withSweeps ? sweepPoints(plan, base) : std::vector<SweepPoint>{};

    std::map<BenchMode, int> byMode;
    auto addModes = [&](bool truths) {
        for (const BenchModeInfo& mode : kBenchModes)
            if (mode.isTruth == truths) {
                byMode[mode.mode] = addConfig(set, base, mode.mode, mode.name);
                set.rows.push_back({byMode[mode.mode], label("modes", name, mode.mode)});
            }
    };
    addModes(/*truths=*/true);
    // The sweeps change sigma: the truths of the other sigmas, all near on Vulkan too.
    std::map<double, int> truthBySigma{{base.render.sigma, byMode.at(BenchMode::NearVulkan)}};
    for (const SweepPoint& p : pts) {
        if (truthBySigma.count(p.sigma)) continue;
        Scene sc = base;
        sc.render.sigma = p.sigma;
        const int t =
            addConfig(set, sc, BenchMode::NearVulkan, "near_vulkan sigma=" + fmt(p.sigma));
        truthBySigma[p.sigma] = t;
        set.rows.push_back({t, label("sweep", name, BenchMode::NearVulkan, "sigma (all near)",
                                     "all near, sigma=" + fmt(p.sigma), p.sigma)});
    }
    addModes(/*truths=*/false);

    std::map<std::string, int> byKey{
        {configKey(base.selector, base.render.sigma), byMode.at(BenchMode::Hybrid)}};
    for (const SweepPoint& p : pts) {
        const std::string key = configKey(p.selector, p.sigma);
        if (!byKey.count(key)) {
            Scene sc = base;
            sc.selector = p.selector;
            sc.render.sigma = p.sigma;
            byKey[key] = addConfig(set, sc, BenchMode::Hybrid, "hybrid " + p.setting);
        }
        set.rows.push_back(
            {byKey[key], label("sweep", name, BenchMode::Hybrid, p.family, p.setting, p.param)});
    }
    linkTruths(set);
    return set;
}

Set scalingSet(const SceneSource& src, const nlohmann::json& doc, const Plan& plan,
               const std::string& group, double param, const std::string& what) {
    Set set;
    const std::string name = sceneName(src.file);
    set.label = name + " " + what;
    Scene s = sceneFromJson(src, doc);
    applyOverrides(s, plan, /*capEntities=*/false);
    set.frames = {0};
    set.times = {0.0};
    set.repeats = plan.scalingRepeats;
    for (const bool truths : {true, false})
        for (const BenchModeInfo& mode : kBenchModes)
            if (mode.isTruth == truths)
                set.rows.push_back({addConfig(set, s, mode.mode, mode.name),
                                    label(group, name, mode.mode, group, what, param)});
    linkTruths(set);
    return set;
}

std::string selectorSummary(const Scene& s) {
    const SelectorConfig& c = s.selector;
    return std::string(toString(c.metric)) + " near_at " + fmt(c.nearAt) + " far_at " +
           fmt(c.farAt) + ", " + std::to_string(c.viewSetSize) + " views, sigma " +
           fmt(s.render.sigma) + ", fade " + std::to_string(c.crossfadeFrames) +
           (c.viewHysteresisDeg > 0 ? ", view hysteresis " + fmt(c.viewHysteresisDeg) : "");
}

std::string sceneName(const std::string& file) {
    return std::filesystem::path(file).stem().string();
}

} // namespace voxtier::bench
