#include "compose/error_budget.hpp"

#include "compose/frame_error.hpp"

#include <algorithm>
#include <array>

namespace voxtier {

namespace {

glm::dvec3 halfExtent(const SpriteSetup& s) {
    return glm::dvec3(s.lattice.dims) * 0.5;
}

} // namespace

double budgetUnitsPerVpx(const SpriteSetup& sprite) {
    return std::min(1.0, cellSizePx(sprite));
}

double predictedBudgetUnits(const SpriteSetup& sprite, ViewId view) {
    return predictedDisplacementVpx(halfExtent(sprite), sprite.lattice.sigma, -sprite.lattice.dir,
                                    view) *
           budgetUnitsPerVpx(sprite);
}

double bestBudgetUnits(const SpriteSetup& sprite, const SelectorConfig& config) {
    return predictedBudgetUnits(sprite, nearestLadderView(config.ladderCap, -sprite.lattice.dir));
}

void ErrorBudgetViews::beginFrame(std::size_t entities, int bakes) {
    current_.resize(entities);
    fades_.resize(entities);
    for (Fade& f : fades_)
        if (f.left > 0) --f.left;
    baking_.clear();
    bakesLeft_ = bakes;
    viewChanges_ = 0;
}

void ErrorBudgetViews::drop(std::size_t entity) {
    if (entity < current_.size()) current_[entity].reset(), fades_[entity].left = 0;
}

bool ErrorBudgetViews::viewFade(std::size_t entity, const SpriteSetup& sprite,
                                const SelectorConfig& config, const IsCached& isCached,
                                float* share, ViewId* from) {
    Fade& f = fades_.at(entity);
    if (f.left <= 0) return false;
    if (predictedBudgetUnits(sprite, f.from) > config.budgetVpx || !isCached(sprite, f.from)) {
        f.left = 0;
        return false;
    }
    // Frame k of N after the switch shows k/(N+1) of the new view, as a tier cross-fade does.
    const int shown = config.crossfadeFrames - f.left + 1;
    *share = float(shown) / float(config.crossfadeFrames + 1);
    *from = f.from;
    return true;
}

std::optional<ViewId> ErrorBudgetViews::choose(std::size_t entity, const SpriteSetup& sprite,
                                               const SelectorConfig& config,
                                               const IsCached& isCached) {
    std::optional<ViewId>& current = current_.at(entity);
    const double budget = config.budgetVpx;
    const auto available = [&](ViewId v) {
        if (isCached(sprite, v)) return true;
        return std::any_of(baking_.begin(), baking_.end(), [&](const auto& b) {
            return b.second == v && b.first->model == sprite.model &&
                   b.first->frame == sprite.frame && b.first->lattice.sigma == sprite.lattice.sigma;
        });
    };
    const auto bake = [&](ViewId v) {
        --bakesLeft_;
        baking_.emplace_back(&sprite, v);
        return v;
    };
    // Hysteresis on the view and level: a view within the budget is kept however the camera
    // wobbles, even when a coarser level would do now. An animated model may need it baked for
    // its new frame: that counts against the bound like any bake.
    if (current && predictedBudgetUnits(sprite, *current) <= budget) {
        if (available(*current)) return current;
        if (bakesLeft_ > 0) return bake(*current);
    }
    // Each level's nearest view and its prediction, computed once (this runs for every entity
    // the selector puts far, each frame).
    struct Level {
        ViewId view;
        double predicted = 0.0;
        int cached = -1; ///< -1 not asked yet, else whether the snapshot is available
    };
    std::array<Level, kViewLadder.size()> levels;
    std::size_t count = 0;
    for (int n : kViewLadder) {
        if (n > config.ladderCap) break;
        const ViewId v = nearestLadderView(n, -sprite.lattice.dir);
        levels[count++] = {v, predictedBudgetUnits(sprite, v)};
    }
    // The levels' nearest views within the budget, coarse to fine. A fresh choice aims at
    // far_at's share of the budget where it can, so the next small move does not switch again;
    // a snapshot already cached (or baking this frame) wins over one that needs a bake.
    const double targets[2] = {budget * std::min(1.0, config.farAt / config.nearAt), budget};
    std::optional<ViewId> pick, pickNeedingBake;
    for (const double target : targets) {
        for (std::size_t k = 0; k < count && !pick; ++k) {
            Level& l = levels[k];
            if (l.predicted > target) continue;
            if (l.cached < 0) l.cached = available(l.view);
            if (l.cached) pick = l.view;
            if (!pickNeedingBake) pickNeedingBake = l.view;
        }
        if (pick) break;
    }
    if (!pick && pickNeedingBake && bakesLeft_ > 0) pick = bake(*pickNeedingBake);
    if (pick && current && !(*pick == *current)) {
        ++viewChanges_;
        if (config.crossfadeFrames > 0) fades_.at(entity) = {*current, config.crossfadeFrames};
    }
    current = pick;
    return pick;
}

} // namespace voxtier
