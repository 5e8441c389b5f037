#pragma once
// The far tier under an error budget (DESIGN.md §5, selector metric "error_budget"): an entity
// is drawn far only from a view whose predicted silhouette displacement (predictedDisplacementVpx)
// is within the budget, and of the views that are, the coarsest ladder level's, so entities share
// snapshots. The selector (lod/selector.hpp) decides the tier from budgetShare with its
// hysteresis band; this picks the view, sticky while it stays within the budget, and never bakes
// more than SelectorConfig::maxBakesPerFrame snapshots in one frame.
#include "core/scene.hpp"
#include "core/sprite.hpp"
#include "impostor_cache/view_set.hpp"

#include <cstddef>
#include <functional>
#include <optional>
#include <vector>

namespace voxtier {

/// Budget units per virtual pixel of a sprite: 1 where a virtual pixel covers at least a screen
/// pixel; its size in screen pixels where it covers less (then the budget is in screen pixels).
double budgetUnitsPerVpx(const SpriteSetup& sprite);
/// The predicted displacement of drawing `sprite` from the snapshot of `view`, in budget units.
double predictedBudgetUnits(const SpriteSetup& sprite, ViewId view);
/// The least predicted displacement (budget units) any view up to the ladder cap offers: the
/// cap level's nearest view (the levels nest, so a finer level is never further away).
double bestBudgetUnits(const SpriteSetup& sprite, const SelectorConfig& config);

/// Per-entity far views under the budget.
class ErrorBudgetViews {
  public:
    /// Whether a snapshot of (sprite's model and frame, view, sprite's sigma) can be drawn
    /// without a bake: cached in memory or on disk (SnapshotCache::availableWithoutBake).
    using IsCached = std::function<bool(const SpriteSetup&, ViewId)>;

    void reset() { current_.clear(), fades_.clear(); }
    /// Starts a frame: `bakes` snapshots may still be baked in it.
    void beginFrame(std::size_t entities, int bakes);
    /// The view `sprite` (entity `entity`) is drawn far from, or nullopt if no view within the
    /// budget can be had this frame without passing the bake bound (then draw it near). Keeps
    /// the entity's current view while that stays within the budget; otherwise the coarsest
    /// level whose nearest view is within the budget, a cached one first.
    std::optional<ViewId> choose(std::size_t entity, const SpriteSetup& sprite,
                                 const SelectorConfig& config, const IsCached& isCached);
    /// The entity is drawn near: the next far frame picks its view afresh.
    void drop(std::size_t entity);
    /// After choose(): whether the entity is inside a view switch's cross-fade
    /// (config.crossfadeFrames > 0), with the share of pixels already showing the new view and
    /// the old view. The old view must still be within the budget and cached; else the switch
    /// is instant (a cross-fade never shows a view past the budget, nor bakes one).
    bool viewFade(std::size_t entity, const SpriteSetup& sprite, const SelectorConfig& config,
                  const IsCached& isCached, float* share, ViewId* from);
    int viewChangesThisFrame() const { return viewChanges_; }
    int bakesLeft() const { return bakesLeft_; }

  private:
    std::vector<std::optional<ViewId>> current_;
    struct Fade {
        ViewId from;
        int left = 0; ///< frames of the cross-fade still to show
    };
    std::vector<Fade> fades_;
    /// Views this frame already asked to bake (a second entity sharing one costs nothing).
    std::vector<std::pair<const SpriteSetup*, ViewId>> baking_;
    int bakesLeft_ = 0;
    int viewChanges_ = 0;
};

} // namespace voxtier
