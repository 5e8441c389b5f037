#include "lod/selector.hpp"

#include "core/sprite_kernel.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <cassert>
#include <cmath>

namespace voxtier {

const char* toString(Tier t) {
    return t == Tier::Near ? "near" : "far";
}

double selectorMetric(SelectorMetric metric, const SelectorInput& in) {
    switch (metric) {
    case SelectorMetric::Distance:
        return in.distance;
    case SelectorMetric::RadiusPx:
        return in.radiusPx;
    case SelectorMetric::ErrorPx:
        return in.radiusPx * std::sin(std::acos(in.viewCos));
    case SelectorMetric::ErrorBudget:
        return in.budgetShare;
    }
    return in.distance;
}

TierSelector::TierSelector(const SelectorConfig& config) : config_(config) {}

void TierSelector::reset() {
    state_.clear();
    initialised_ = false;
}

int metricSideFast(const SelectorInput& in, double threshold) {
    const double c = in.viewCos, r = in.radiusPx;
    // Outside these ranges the bound's premises fail (1 - c inexact, theta * cot(theta) > 1, a
    // subnormal or overflowing product): the IEEE value decides.
    if (!(c >= 0.5 && c <= 1.0) || !(r >= 1e-200 && r <= 1e200) ||
        !(threshold > 0.0 && threshold <= 1e200))
        return 0;
    const double bound = r * std::sqrt((1.0 - c) * (1.0 + c));
    const double slack = kErrorPxSlack * threshold;
    return bound > threshold + slack ? 1 : bound < threshold - slack ? -1 : 0;
}

int metricSide(SelectorMetric metric, const SelectorInput& in, double threshold) {
    if (metric == SelectorMetric::ErrorPx)
        if (const int side = metricSideFast(in, threshold)) return side;
    const double m = selectorMetric(metric, in);
    return m > threshold ? 1 : m < threshold ? -1 : 0; // a NaN metric is past no threshold
}

bool TierSelector::pastFar(const SelectorInput& in) const {
    const int side = metricSide(config_.metric, in, config_.farAt);
    return config_.metric == SelectorMetric::Distance ? side > 0 : side < 0;
}

bool TierSelector::pastNear(const SelectorInput& in) const {
    const int side = metricSide(config_.metric, in, config_.nearAt);
    return config_.metric == SelectorMetric::Distance ? side < 0 : side > 0;
}

SelectorStats TierSelector::sum(SelectorStats a, const SelectorStats& b) {
    a.nearCount += b.nearCount;
    a.farCount += b.farCount;
    a.switchesToFar += b.switchesToFar;
    a.switchesToNear += b.switchesToNear;
    a.fading += b.fading;
    return a;
}

bool TierSelector::beginFrame(std::size_t entities, bool partial) {
    viewChangesThisFrame_.store(0, std::memory_order_relaxed);
    if (partial) {
        assert(initialised_ && entities == state_.size() && "a partial frame follows a whole one");
        return false;
    }
    const bool first = !initialised_;
    if (first) state_.assign(entities, State{});
    assert(entities == state_.size() && "entity count changed: call reset()");
    initialised_ = true;
    return first;
}

void TierSelector::step(std::size_t i, const SelectorInput& in, bool first, SelectorStats& st) {
    State& s = state_[i];
    // One comparison an entity (its tier decides which): error_px's rarely needs the metric's
    // IEEE value (metricSideFast).
    if (first) {
        // The first frame assigns tiers without counting switches.
        s.tier = pastFar(in) ? Tier::Far : Tier::Near;
    } else {
        if (s.fadeLeft > 0) --s.fadeLeft;
        const Tier before = s.tier;
        if (s.tier == Tier::Near && pastFar(in)) {
            s.tier = Tier::Far;
            ++st.switchesToFar;
        } else if (s.tier == Tier::Far && pastNear(in)) {
            s.tier = Tier::Near;
            s.view = -1; // a later return to far starts from the nearest view again
            ++st.switchesToNear;
        }
        if (s.tier != before && config_.crossfadeFrames > 0) {
            s.fadeFrom = before;
            s.fadeLeft = config_.crossfadeFrames;
        }
    }
    (s.tier == Tier::Near ? st.nearCount : st.farCount)++;
    st.fading += s.fadeLeft > 0;
}

SelectorStats TierSelector::update(std::span<const SelectorInput> inputs) {
    const bool first = beginFrame(inputs.size());
    // Each entity's state moves on its own; only the counts are shared, summed per chunk.
    return tbb::parallel_reduce(
        tbb::blocked_range<std::size_t>(0, inputs.size(), 4096), SelectorStats{},
        [&](const tbb::blocked_range<std::size_t>& range, SelectorStats st) {
            for (std::size_t i = range.begin(); i != range.end(); ++i)
                step(i, inputs[i], first, st);
            return st;
        },
        sum);
}

SelectorStats TierSelector::update(std::span<const SelectorInput> inputs,
                                   std::span<const std::uint32_t> ids) {
    beginFrame(inputs.size(), true);
    return tbb::parallel_reduce(
        tbb::blocked_range<std::size_t>(0, ids.size(), 4096), SelectorStats{},
        [&](const tbb::blocked_range<std::size_t>& range, SelectorStats st) {
            for (std::size_t k = range.begin(); k != range.end(); ++k)
                step(ids[k], inputs[ids[k]], false, st);
            return st;
        },
        sum);
}

bool TierSelector::fading(std::size_t entity, float* fraction, Tier* from) const {
    const State& s = state_[entity];
    if (s.fadeLeft <= 0) return false;
    // Frame k of N after the switch shows k/(N+1) of the new tier: never all-old, never all-new.
    const int shown = config_.crossfadeFrames - s.fadeLeft + 1;
    if (fraction) *fraction = float(shown) / float(config_.crossfadeFrames + 1);
    if (from) *from = s.fadeFrom;
    return true;
}

int TierSelector::chooseView(std::size_t entity, glm::dvec3 towardViewer,
                             std::span<const glm::dvec3> views) {
    assert(!views.empty());
    int best = 0;
    double bestDot = glm::dot(views[0], towardViewer);
    for (std::size_t v = 1; v < views.size(); ++v) {
        const double d = glm::dot(views[v], towardViewer);
        if (d > bestDot) bestDot = d, best = int(v);
    }
    return chooseView(entity, towardViewer, views, best);
}

int TierSelector::chooseView(std::size_t entity, glm::dvec3 towardViewer,
                             std::span<const glm::dvec3> views, int best) {
    if (entity >= state_.size()) return best;
    State& s = state_[entity];
    if (s.view >= 0 && s.view < int(views.size()) && s.view != best &&
        config_.viewHysteresisDeg > 0.0) {
        const double len = glm::length(towardViewer);
        const auto angle = [&](int v) {
            return std::acos(
                std::clamp(glm::dot(views[std::size_t(v)], towardViewer) / len, -1.0, 1.0));
        };
        if (angle(s.view) - angle(best) <= glm::radians(config_.viewHysteresisDeg)) return s.view;
    }
    if (s.view >= 0 && s.view != best)
        viewChangesThisFrame_.fetch_add(1, std::memory_order_relaxed);
    s.view = best;
    return best;
}

float ditherThreshold(int x, int y) {
    return kernel::vtDitherThreshold({x, y});
}

} // namespace voxtier
