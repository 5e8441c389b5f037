#pragma once
// The frame's LOD plan (CONTRACT.md §5, step 2 of the recipe in §6): each entity's tier, its
// cross-fade and the snapshot view the far tier draws it from, with the cost model the error
// budget's cost bound reads. lod/ plans, compose/ draws: FrameRenderer hands the planner the
// frame's sprites and what the snapshot cache holds, draws the plan, and hands back what the
// drawing measured (FramePlanner::observe).
#include "core/near_rate.hpp"
#include "core/scene.hpp"
#include "core/shared_vector.hpp"
#include "core/sprite.hpp"
#include "core/view_set.hpp"
#include "lod/error_budget.hpp"
#include "lod/selector.hpp"

#include <cstddef>
#include <cstdint>
#include <functional>
#include <optional>
#include <span>
#include <vector>

namespace voxtier {

/// What one entity does this frame: its tier, an optional cross-fade (both tiers draw it, with
/// complementary dither masks) and the snapshot view the far tier uses.
struct EntityPlan {
    Tier tier = Tier::Near;
    float fade = 0.0f; ///< share of pixels already showing `tier` (0 = no cross-fade)
    Tier fadeFrom = Tier::Near;
    std::optional<ViewId> view; ///< far view (when the far tier draws the entity)
    /// A view switch's cross-fade (fade > 0, both tiers far): the old view, drawn by the far tier
    /// on the pixels the new one leaves (the complementary dither half).
    std::optional<ViewId> fadeFromView;
    bool drawsNear() const { return tier == Tier::Near || (fade > 0.0f && fadeFrom == Tier::Near); }
    bool drawsFar() const { return tier == Tier::Far || (fade > 0.0f && fadeFrom == Tier::Far); }
    bool operator==(const EntityPlan&) const = default;
};

/// Who a frame's plan may put far: nobody (reference and near frames), everybody (far frames:
/// the selector still runs, for its views), or the selector (hybrid frames, with cross-fades and,
/// under metric error_budget, the budget's views and cost bound).
enum class PlanMode { AllNear, AllFar, Hybrid };

/// The planner's share of a frame's figures (FrameStats has a field for each).
struct PlanStats {
    int switchesToFar = 0, switchesToNear = 0, viewChanges = 0;
    int fading = 0;       ///< entities drawn by both tiers (cross-fade)
    int bakesGivenUp = 0; ///< metric error_budget: bakes given up under the cost bound
    /// Metric error_budget: far sprites drawn near because the far tier as a whole costs more far
    /// than near by the cost bound's costs (ErrorBudgetViews::keepAffordableBakes).
    int heldNear = 0;
    /// Metric error_budget: far entities drawn near unscanned while the cost bound pauses bakes
    /// (ErrorBudgetViews::bakesPaused): those whose current view was not both within the budget
    /// and cached (a scan might have found them another cached one).
    int pausedNear = 0;
    /// Metric error_budget: the plan's questions that reached the snapshot cache (the rest were
    /// answered by SharedCacheAnswers, this plan's or kept from the plans before).
    int cacheQuestions = 0;
    double worstVpx = 0.0; ///< largest predictedBudgetUnits of a far-drawn entity
    /// Far-drawn entities whose predictedBudgetUnits is over 1 vpx: where the image is visibly
    /// approximate (the render command's warning counts them; it read each far sprite again on
    /// one core, ~5 ms a frame at 100,000 far tanks, for what the plan had found).
    int farOverOneVpx = 0;
    /// Entities planned afresh: every one, or, planning what changed, the entities whose sprite
    /// changed and those inside a cross-fade (FramePlanner::plan's `changed`).
    int planned = 0;
    /// Where the plan's time went (ms), in the order plan() takes the steps; they add up to its
    /// time but for the set-up of its arrays. On a 16-core host a step that does not shrink with
    /// the cores shows here, where the selection's total hides it.
    struct PhaseMs {
        double inputs = 0.0; ///< each entity's selector inputs (distance, radius, angle or budget)
        double tiers = 0.0;  ///< the selector's hysteresis over every entity
        /// each entity's tier applied and its far view: error_px the nearest view and its
        /// prediction; error_budget the current view kept or the levels scanned (prepare)
        double views = 0.0;
        double choices = 0.0;     ///< error_budget: the views handed out under the bake bound
        double costBound = 0.0;   ///< error_budget: bakes given up under the cost bound
        double predictions = 0.0; ///< error_budget: the far entities' predictions; the worst
    } ms;
};

/// How one frame is planned.
struct PlanSettings {
    PlanMode mode = PlanMode::Hybrid;
    /// Metric error_budget: give up bakes that cost more than the near time the frame's far
    /// sprites save (ErrorBudgetViews::keepAffordableBakes), by the costs measured on earlier
    /// frames, or by `bakeCosts` where set. false: only the bake bound limits the bakes.
    bool costAwareBakes = true;
    std::optional<BakeCosts> bakeCosts;
    /// What the snapshot cache can give without a bake: in memory (preferred), and without a
    /// bake at all (also a file in the on-disk store; may be empty). ErrorBudgetViews::choose.
    ErrorBudgetViews::IsCached inMemory, withoutBake;
    /// What `inMemory` answers changed since the count `since` of its changes (nullopt: none
    /// known): the views about which it may answer otherwise now appended to `changed`
    /// (`complete` true), or `complete` false when that cannot be told; and the count now.
    struct InMemoryChanges {
        std::uint64_t count = 0;
        bool complete = false;
    };
    using InMemoryChangesSince = std::function<InMemoryChanges(std::optional<std::uint64_t> since,
                                                               std::vector<CachedView>& changed)>;
    /// Where set, the error budget's plans keep `inMemory`'s answers from one plan to the next
    /// while `inMemoryEpoch` stays the same (it names everything else they depend on: the
    /// models' versions, the cache) and asks again only about the views this names. Empty:
    /// each plan asks afresh.
    InMemoryChangesSince inMemoryChangesSince;
    std::uint64_t inMemoryEpoch = 0;
};

/// What drawing one frame measured, for the cost model (FrameStats' figures of the same names).
struct FrameCostSample {
    int bakes = 0;
    double bakeMs = 0.0; ///< the far tier making sure its snapshots exist
    /// Of bakeMs, the snapshot cache's own split: the bakes themselves, and the Embree scene
    /// builds with the on-disk store's reads and writes.
    double bakeWorkMs = 0.0, sceneAndStoreMs = 0.0;
    double nearMs = 0.0, nearUploadMs = 0.0, blitMs = 0.0;
    /// Of blitMs, the far pass's snapshot uploads (each snapshot's once, when first drawn).
    double farSnapshotsMs = 0.0;
    double planMs = 0.0; ///< the planner's own time (FrameStats::hostSelectMs)
    /// A hybrid frame under metric error_budget: the only frames whose near cost and planning
    /// time the cost bound reads.
    bool planned = false;
};

/// Running averages of what a bake, a near sprite and a far blit cost, over the frames drawn
/// so far (CONTRACT.md §5, cost bound).
class CostModel {
  public:
    /// The costs measured so far (BakeCosts::known() once a bake and the near tier were).
    const BakeCosts& costs() const { return costs_; }
    /// Learns from a drawn frame: `sprites` drawn as `plan` says, near sprites at `rate`.
    /// `nearFixedMs` measures the near tier's per-frame cost whatever it draws (compose draws an
    /// empty frame); it is asked only when a planned frame drew near sprites.
    void observe(std::span<const SpriteSetup> sprites, std::span<const std::uint32_t> visible,
                 std::span<const EntityPlan> plan, const FrameCostSample& sample, NearRate rate,
                 const std::function<double()>& nearFixedMs);

  private:
    BakeCosts costs_;
    /// costs_.nearMsPerUnit as decayed sums of near sprite ms and near cost units.
    struct {
        double ms = 0.0, units = 0.0;
    } nearSums_;
    /// Planned frames whose near tier drew a sprite (the first is no sample).
    int nearFramesSeen_ = 0;
};

/// What persists of the LOD policy between frames of one scene: the selector's per-entity
/// state, the error budget's views and the cost model.
class FramePlanner {
  public:
    explicit FramePlanner(const SelectorConfig& config) : selector_(config) {}

    /// Each entity's plan this frame, by `config` (the scene's selector settings). `sprites` is
    /// indexed by entity id, `visible` lists the visible ones in ascending id. The per-entity
    /// steps run in parallel, into arrays the planner keeps: a frame allocates nothing once the
    /// entity count is known. The result stays as it is when later frames are planned.
    /// `changed` (optional) marks per entity id the sprites that differ from those of this
    /// planner's previous call in what a plan reads, which is all but their animation frame and
    /// skip rule (SpriteStore::reposed; SpriteStore::changed too): given it, a frame that follows a
    /// planned frame of the same mode and config plans only those entities and the ones inside a
    /// cross-fade, and keeps every other entity's plan (the same plan a whole frame gives).
    /// `selection` (optional) is per entity id selectionInputs(sprites[id]), as a SpriteStore
    /// keeps them (SpriteStore::selectionInputs): what the plan reads of each sprite, but for the
    /// model, frame and sigma that the error budget's questions to the cache name; without it the
    /// plan computes them from the sprites.
    SharedVector<EntityPlan> plan(std::span<const SpriteSetup> sprites,
                                  std::span<const std::uint32_t> visible,
                                  const SelectorConfig& config, const PlanSettings& settings,
                                  PlanStats& stats, std::span<const std::uint8_t> changed = {},
                                  std::span<const SpriteSelectionInputs> selection = {});
    /// The same, for sprites without a list of the visible ones (found here).
    SharedVector<EntityPlan> plan(std::span<const SpriteSetup> sprites,
                                  const SelectorConfig& config, const PlanSettings& settings,
                                  PlanStats& stats);
    /// After drawing the plan: what it cost (CostModel::observe).
    void observe(std::span<const SpriteSetup> sprites, std::span<const std::uint32_t> visible,
                 std::span<const EntityPlan> plan, const FrameCostSample& sample, NearRate rate,
                 const std::function<double()>& nearFixedMs) {
        costs_.observe(sprites, visible, plan, sample, rate, nearFixedMs);
    }

    TierSelector& selector() { return selector_; }
    const CostModel& costModel() const { return costs_; }

  private:
    /// Metric error_budget, for a visible entity the selector draws far: the view within the
    /// budget (plan.view), or the entity drawn near. `prepared`: budgetViews_.prepare() for this
    /// entity, this frame. In entity order: the views share the frame's bake bound.
    void planBudgetView(std::size_t entity, const SpriteSetup& sprite,
                        const SpriteSelectionInputs& selection, const SelectorConfig& config,
                        const PlanSettings& settings, const ErrorBudgetViews::Prepared& prepared,
                        EntityPlan& plan);
    /// After the entity's view: the view switch's cross-fade, if it is inside one.
    void fadeBudgetView(std::size_t entity, const SpriteSetup& sprite,
                        const SpriteSelectionInputs& selection, const SelectorConfig& config,
                        const PlanSettings& settings, EntityPlan& plan);
    /// Metric error_budget, cost bound on: where the far tier was held near and still is, weighed
    /// over the visible entities the selector draws far (their tiers set by `tierOf`), draws them
    /// near and returns true: the frame then chooses no view.
    template <class TierOf, class ForEach>
    bool holdFarTier(std::span<const SpriteSelectionInputs> in, const PlanSettings& settings,
                     const TierOf& tierOf, const ForEach& forEach, std::vector<EntityPlan>& plan,
                     PlanStats& st);
    /// Metric error_budget: starts the plan's shared answers of the cache, kept from the plan
    /// before where the settings tell what changed since.
    void beginCacheAnswers(const PlanSettings& settings);
    /// Metric error_budget, after every entity's view: the bakes the frame can afford (`in`: the
    /// sprites' selection inputs). Returns the bakes given up.
    int keepAffordableBakes(std::span<const SpriteSetup> sprites,
                            std::span<const SpriteSelectionInputs> in,
                            std::span<const std::uint32_t> visible, const PlanSettings& settings,
                            std::vector<EntityPlan>& plan);

    TierSelector selector_;
    ErrorBudgetViews budgetViews_; ///< far views under metric error_budget
    CostModel costs_;
    // Per entity, kept between frames (resized only when the entity count changes): the plan,
    // and the selector's inputs (the error budget's: error_px steps each entity as it derives
    // them).
    SharedVectorOwner<EntityPlan> plan_;
    std::vector<SelectorInput> inputs_;
    /// selectionInputs of each sprite, where plan() was given none
    std::vector<SpriteSelectionInputs> ownSelection_;
    std::vector<std::optional<ViewId>> drawnFrom_;
    std::vector<double> predicted_; ///< predictedBudgetUnits of each far-drawn visible entity
    /// error_budget: what each far entity's view choice reads of no other entity, this frame
    std::vector<ErrorBudgetViews::Prepared> prepared_;
    SharedCacheAnswers cacheAnswers_; ///< error_budget: the cache's answers, kept across plans
    /// The count of the cache's changes the answers were kept through, and under which epoch
    /// (PlanSettings::inMemoryChangesSince); the views changed since, this plan.
    std::optional<std::uint64_t> answersThrough_;
    std::uint64_t answersEpoch_ = 0;
    std::vector<CachedView> answersChanged_;
    /// error_budget: what each entity's view took this frame (not far: none; a view kept in the
    /// parallel pass; one chosen in the serial pass)
    enum class BudgetStep : std::uint8_t { Near, Kept, Choose };
    std::vector<BudgetStep> budgetStep_;
    std::vector<std::uint8_t> mayUseABake_; ///< error_budget: 1 where budgetStep_ is Choose
    std::vector<std::uint32_t> work_;       ///< the entities a frame plans afresh
    /// The previous call went through the selector, with this mode and config: a frame with
    /// the sprites' changes since then may plan only what changed.
    bool chained_ = false;
    PlanMode lastMode_ = PlanMode::AllNear;
    SelectorConfig lastConfig_;
};

} // namespace voxtier
