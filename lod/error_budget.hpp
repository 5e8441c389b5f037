#pragma once
// The far tier under an error budget (CONTRACT.md §5, selector metric "error_budget"): an entity
// is drawn far only from a view whose predicted silhouette displacement (predictedDisplacementVpx)
// is within the budget, and of the views that are, the coarsest ladder level's, so entities share
// snapshots. The selector (lod/selector.hpp) decides the tier from budgetShare with its
// hysteresis band; this picks the view, sticky while it stays within the budget, and never bakes
// more than SelectorConfig::maxBakesPerFrame snapshots in one frame.
#include "core/near_rate.hpp"
#include "core/scene.hpp"
#include "core/sprite.hpp"
#include "core/view_set.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_reduce.h>

#include <array>
#include <atomic>
#include <cstddef>
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <vector>

namespace voxtier {

/// Budget units per virtual pixel of a sprite: 1 where a virtual pixel covers at least a screen
/// pixel; its size in screen pixels where it covers less (then the budget is in screen pixels).
double budgetUnitsPerVpx(const SpriteSetup& sprite);
/// The predicted displacement of drawing `sprite` from the snapshot of `view`, in budget units.
double predictedBudgetUnits(const SpriteSetup& sprite, ViewId view);
/// The same from the sprite's selection inputs (SpriteSelectionInputs: what the store keeps).
double predictedBudgetUnits(const SpriteSelectionInputs& sprite, ViewId view);
/// The same for the view whose unit vector (viewDirection) is `direction`.
double predictedBudgetUnits(const SpriteSelectionInputs& sprite, glm::dvec3 direction);
/// The least predicted displacement (budget units) any view up to the ladder cap offers: the
/// cap level's nearest view (the levels nest, so a finer level is never further away).
double bestBudgetUnits(const SpriteSetup& sprite, const SelectorConfig& config);
/// The same from the sprite's selection inputs.
double bestBudgetUnits(const SpriteSelectionInputs& sprite, const SelectorConfig& config);

/// What the planner knows of the frame's costs (measured on earlier frames, or given by a test):
/// a bake, drawing a sprite near per unit of its near cost (nearCostUnits: its cells where it
/// is drawn cell-rate, else its rectangle pixels; the near tier's per-frame cost excluded) and
/// blitting it far per pixel of its screen rectangle.
struct BakeCosts {
    double msPerBake = 0.0;
    double nearMsPerUnit = 0.0;
    double blitMsPerPx = 0.0;
    /// The planner's own time per frame (selection and views): all-near spends none of it, so
    /// the far sprites must save it too.
    double planMs = 0.0;
    /// The near tier's rate (what a sprite's nearCostUnits are).
    NearRate nearRate = NearRate::Auto;
    /// Both a bake and the near tier have been measured: the cost bound can apply.
    bool known() const { return msPerBake > 0.0 && nearMsPerUnit > 0.0; }
    /// What drawing `sprite` far instead of near saves this frame (ms; negative if nothing):
    /// nearMs(sprite) - farMs(sprite).
    double farSavingMs(const SpriteSetup& sprite) const;
    /// What drawing `sprite` near costs by these costs (ms): its near cost units at the near rate.
    double nearMs(const SpriteSetup& sprite) const;
    /// What drawing `sprite` far costs by these costs (ms): its screen rectangle at the blit's
    /// rate.
    double farMs(const SpriteSetup& sprite) const;
    /// The same two from the sprite's selection inputs (its sizes kept there): the same values
    /// but for a sprite past 2^32 - 1 cells under a forced cell rate (SpriteSelectionInputs).
    double nearMs(const SpriteSelectionInputs& sprite) const;
    double farMs(const SpriteSelectionInputs& sprite) const;
};

/// What a far tier costs drawn far and drawn near (ms), and how many sprites it has.
struct TierMs {
    double far = 0.0, near = 0.0;
    int sprites = 0;
};
/// The sum of `of(i)` (a TierMs: a far sprite's BakeCosts::farMs and nearMs and 1, or {} for an
/// entity not in the tier) over the entities i < n, on every core and the same sums whatever the
/// threads: what the cost bound weighs the far tier by (ErrorBudgetViews::weighFarTier).
template <class Of> TierMs sumTierMs(std::size_t n, const Of& of) {
    return tbb::parallel_deterministic_reduce(
        tbb::blocked_range<std::size_t>(0, n, 1024), TierMs{},
        [&](const tbb::blocked_range<std::size_t>& r, TierMs s) {
            for (std::size_t i = r.begin(); i != r.end(); ++i) {
                const TierMs t = of(i);
                s.far += t.far, s.near += t.near, s.sprites += t.sprites;
            }
            return s;
        },
        [](TierMs a, const TierMs& b) {
            return TierMs{a.far + b.far, a.near + b.near, a.sprites + b.sprites};
        });
}

/// The snapshots a planner's question to the cache names: a model and animation frame of the
/// scene, and a view (at any sigma).
struct CachedView {
    int model = 0, frame = 0;
    ViewId view;
};

/// The answers of an ErrorBudgetViews::IsCached for a frame's plan, shared by the threads that
/// plan it: each distinct question (the sprite's model, animation frame and sigma, and the view)
/// goes to the cache once. At 100,000 tanks the far entities ask ~100,000-300,000 times a frame
/// about ~20,000-30,000 snapshots, and the snapshot cache answers each under a lock every core
/// takes, through a hash map and a version map in memory far from the core (~400 ns an answer).
/// The answers may be kept from plan to plan (beginKeeping): ~93 % of a moving frame's questions
/// are the frame before's, and a plan then asks the cache only about the new ones and those whose
/// snapshots changed. The cache must not change while a plan asks. Lock-free: a question is
/// claimed by one thread, which asks the cache; a thread with the same question waits for that
/// answer.
class SharedCacheAnswers {
  public:
    SharedCacheAnswers();
    ~SharedCacheAnswers();
    SharedCacheAnswers(const SharedCacheAnswers&) = delete;
    SharedCacheAnswers& operator=(const SharedCacheAnswers&) = delete;

    /// Starts a plan that forgets every answer.
    void begin();
    /// Starts a plan that keeps the answers of the plans since the last begin(), but for the
    /// questions about `changed` (their answers may differ now), which go to the cache again.
    /// Forgets all instead once the table is half full, so that a question is found in a few
    /// probes.
    void beginKeeping(std::span<const CachedView> changed);
    /// isCached(sprite, view), asked of `isCached` only the first time since it was forgotten.
    bool ask(const SpriteSetup& sprite, ViewId view,
             const std::function<bool(const SpriteSetup&, ViewId)>& isCached);
    /// The questions ask() passed on to the cache since the plan began.
    std::size_t askedOfTheCache() const { return asked_.load(std::memory_order_relaxed); }

  private:
    struct Slot;
    /// A power of two; past kMaxProbes slots taken around a question's place, the cache is
    /// asked directly (a plan about more snapshots than the table holds stays correct).
    std::unique_ptr<Slot[]> slots_;
    std::uint32_t generation_ = 0;      ///< begin()'s count: a slot of another generation is empty
    std::atomic<std::size_t> used_{0};  ///< slots taken in this generation
    std::atomic<std::size_t> asked_{0}; ///< askedOfTheCache()
};

/// Per-entity far views under the budget.
class ErrorBudgetViews {
  public:
    /// Whether a snapshot of (sprite's model and frame, view, sprite's sigma) can be drawn
    /// without a bake: cached in memory or on disk (SnapshotCache::availableWithoutBake).
    using IsCached = std::function<bool(const SpriteSetup&, ViewId)>;

    void reset() {
        current_.clear(), fades_.clear(), farTierHeld_ = false;
        refusedInARow_ = 0, askAgainAt_ = 0;
    }
    /// Starts a frame: `bakes` snapshots may still be baked in it.
    void beginFrame(std::size_t entities, int bakes);
    /// The view `sprite` (entity `entity`) is drawn far from, or nullopt if no view within the
    /// budget can be had this frame without passing the bake bound (then draw it near). Keeps
    /// the entity's current view while that stays within the budget; otherwise the coarsest
    /// level whose nearest view is within the budget, a cached one first. `withoutBake` (may be
    /// empty): a view that can be had without a bake although not cached (a file in the on-disk
    /// store). It spares the bake bound but is never preferred: which files a shared directory
    /// holds depends on other processes and earlier runs, and the views a frame picks must not
    /// (a render is the same whoever baked its snapshots; CONTRACT.md §5).
    std::optional<ViewId> choose(std::size_t entity, const SpriteSetup& sprite,
                                 const SelectorConfig& config, const IsCached& isCached,
                                 const IsCached& withoutBake = {});

    /// The budget's levels as choose() scans them, coarse to fine: the first cached view within
    /// its targets, or, when none is, every view within them in the scan's order.
    struct LevelScan {
        std::optional<ViewId> cachedPick;
        std::array<ViewId, kViewLadder.size()> met{};
        int metCount = 0;
    };
    /// What choose() reads that no other entity's choice changes: whether the current view is
    /// within the budget and cached, and (when it is not both) the level scan. Only the bake
    /// hand-out is left to the serial pass, so a frame prepares its far entities in parallel;
    /// const, and thread-safe where `isCached` is (SnapshotCache's is).
    struct Prepared {
        bool currentWithin = false, currentCached = false;
        /// predictedBudgetUnits of the current view (0 without one)
        double currentUnits = 0.0;
        LevelScan scan; ///< where not settled()
        /// The current view is within the budget and cached: choose() keeps it and changes
        /// nothing shared (no bake, no view change), so such entities need no serial pass.
        bool settled() const { return currentWithin && currentCached; }
    };
    Prepared prepare(std::size_t entity, const SpriteSetup& sprite, const SelectorConfig& config,
                     const IsCached& isCached) const;
    /// The same with the sprite's selection inputs (selectionInputs(sprite), as a SpriteStore
    /// keeps them), which its predictions read in place of the sprite.
    Prepared prepare(std::size_t entity, const SpriteSetup& sprite,
                     const SpriteSelectionInputs& selection, const SelectorConfig& config,
                     const IsCached& isCached) const;
    /// choose() given prepare()'s result for this entity, computed this frame before any
    /// choice and with the `isCached` choose() would be given: the same view. Once bakesLeft()
    /// is 0 no call adds a bake, and a call changes nothing another entity's reads: such calls
    /// may run in parallel over distinct entities.
    std::optional<ViewId> choose(std::size_t entity, const SpriteSetup& sprite,
                                 const SelectorConfig& config, const Prepared& prepared,
                                 const IsCached& withoutBake = {});
    /// choose() for an entity whose prepare() was settled(): its current view. Reads and writes
    /// nothing another entity's choice does, so settled entities may be kept in parallel.
    ViewId keep(std::size_t entity) const { return *current_.at(entity); }
    /// The entity is drawn near: the next far frame picks its view afresh. Changes only this
    /// entity's state (may run in parallel over distinct entities).
    void drop(std::size_t entity);
    /// After choose(): whether the entity is inside a view switch's cross-fade
    /// (config.crossfadeFrames > 0), with the share of pixels already showing the new view and
    /// the old view. The old view must still be within the budget and cached; else the switch
    /// is instant (a cross-fade never shows a view past the budget, nor bakes one). Changes only
    /// this entity's state (may run in parallel over distinct entities).
    bool viewFade(std::size_t entity, const SpriteSetup& sprite, const SelectorConfig& config,
                  const IsCached& isCached, float* share, ViewId* from);
    /// The same with the sprite's selection inputs (as prepare).
    bool viewFade(std::size_t entity, const SpriteSetup& sprite,
                  const SpriteSelectionInputs& selection, const SelectorConfig& config,
                  const IsCached& isCached, float* share, ViewId* from);
    /// Ends the frame's choices under the cost bound (CONTRACT.md §5). First the far tier as a
    /// whole: where drawing its sprites far costs more than drawing them near (the sums of
    /// BakeCosts::farMs and nearMs over them, with a hysteresis band: held near from far costing
    /// kHoldNearAbove times near, let go below kLetGoBelow), every far sprite is drawn near this
    /// frame and every bake is given up; the views of those drawn from a cached snapshot are kept
    /// (while the costs say so the tier stays near without a scan, and goes back to the same
    /// views when they change), the others dropped. Else, while the frame's bakes and planning
    /// cost more than the near time the far sprites save, the bake that saves least (its users'
    /// farSavingMs, summed) is given up if it saves less than it costs, and its users are drawn
    /// near this frame. `drawnFrom[i]` is the view entity i is drawn far from (nullopt: near).
    /// `mayUseABake[i]`, where given, is 0 for an entity whose view is certainly no bake of this
    /// frame (a view kept because it is cached: no entity asks to bake a view the frame's cache
    /// answers hold cached), whose bake is then not looked up. `selection`, where given (one per
    /// sprite), is the sprites' selection inputs, whose sizes are read in place of the sprites'.
    /// Returns the entities drawn near instead, in ascending order (their views dropped unless
    /// the tier was held near).
    std::vector<std::size_t>
    keepAffordableBakes(std::span<const SpriteSetup> sprites,
                        const std::vector<std::optional<ViewId>>& drawnFrom, const BakeCosts& costs,
                        std::span<const std::uint8_t> mayUseABake = {},
                        std::span<const SpriteSelectionInputs> selection = {});
    /// Far above near by this factor, the far tier is held near (keepAffordableBakes); below
    /// kLetGoBelow it is let go. Between, it stays as it was: costs learnt frame by frame wobble,
    /// and a tier that went back and forth with them would pop every frame.
    static constexpr double kHoldNearAbove = 1.25;
    static constexpr double kLetGoBelow = 0.8;
    /// Far sprites keepAffordableBakes held near this frame (the far tier's, or 0).
    int heldNearThisFrame() const { return heldNearCount_; }
    /// Whether the far tier is held near (keepAffordableBakes's hysteresis state): a planner may
    /// then weigh the tier before any view is chosen (weighFarTier) and, while it stays held,
    /// choose none.
    bool farTierHeld() const { return farTierHeld_; }
    /// Weighs the far tier: its far sprites cost `farMs` drawn far and `nearMs` drawn near (sums of
    /// BakeCosts::farMs and nearMs). Whether it is held near, with the hysteresis band; updates
    /// farTierHeld().
    bool weighFarTier(double farMs, double nearMs);
    /// Whether the cost bound pauses bakes this frame: the last frame that asked for bakes had
    /// every one given up as saving less than it costs (not for a held tier). While paused, an
    /// entity without a cached view within the budget is drawn near with its levels unscanned
    /// (prepare() scans nothing; choose() returns nullopt and drops its view): its bake would be
    /// given up again, and on a GPU, whose near tier makes no bake pay, the scans and the cost
    /// bound's weighing of bakes it gives up were most of a 100,000-tank frame's selection. The
    /// pause lasts 1 frame after the first such frame and doubles with each in a row, up to
    /// kLongestBakePause; a frame that keeps a bake, or with no pause asks none, ends the run.
    bool bakesPaused() const { return frame_ < askAgainAt_; }
    /// The pause's rule for an entity `prepared` this frame: where bakes are paused and its
    /// current view is not both within the budget and cached, drops that view and returns true
    /// (draw it near, unscanned). What choose() does first, and a planner that hands out no
    /// choice to such entities asks instead.
    bool waitsOutThePause(std::size_t entity, const Prepared& prepared);
    /// Refusals in a row counted (each doubles the pause), and the longest pause they give.
    static constexpr int kRefusalsCounted = 5;
    static constexpr int kLongestBakePause = (1 << kRefusalsCounted) - 1;
    int viewChangesThisFrame() const { return viewChanges_; }
    int bakesLeft() const { return bakesLeft_; }
    /// Views this frame asks to bake (after keepAffordableBakes: the ones it kept).
    std::size_t bakesAsked() const { return baking_.size(); }

  private:
    /// A snapshot as the planner tells them apart: the requesting sprite's model, frame, sigma.
    struct BakeKey {
        int model = 0;
        int frame = 0;
        double sigma = 1.0;
        ViewId view;
        bool operator==(const BakeKey&) const = default;
    };
    static BakeKey keyOf(const SpriteSetup& sprite, ViewId view) {
        return {sprite.model, sprite.frame, sprite.lattice.sigma, view};
    }
    /// The frame's bakes by key, each with its index in baking_: open addressing, linear probing,
    /// at most half full. Looked up for every met level of every entity waiting for a bake (up
    /// to five levels for each of ~80,000 tanks a frame where bakes are scarce, nearly all
    /// misses): a miss is mostly one probe of a table that stays in the cache, where a node-based
    /// set hashed and walked a bucket list (the choices step 5.0-5.2 ms there, 3.5-3.7 with this).
    class BakeTable {
      public:
        static constexpr std::size_t kNone = ~std::size_t(0);
        void clear();
        /// The key's index, or kNone.
        std::size_t find(const BakeKey& key) const;
        /// A key not in the table.
        void insert(const BakeKey& key, std::size_t index);

      private:
        static std::size_t hash(const BakeKey& key);
        struct Slot {
            BakeKey key;
            std::size_t index = kNone; ///< kNone: empty
        };
        std::vector<Slot> slots_; ///< a power of two, or empty
        std::size_t used_ = 0;
    };

    std::vector<std::optional<ViewId>> current_;
    struct Fade {
        ViewId from;
        int left = 0; ///< frames of the cross-fade still to show
    };
    std::vector<Fade> fades_;
    /// Views this frame already asked to bake (a second entity sharing one costs nothing), in
    /// the order asked, and by key (looked up for every level of every far entity).
    std::vector<BakeKey> baking_;
    BakeTable bakingIndex_;
    int bakesLeft_ = 0;
    /// Counted through std::atomic_ref: the choices past the spent bound run in parallel.
    int viewChanges_ = 0;
    /// keepAffordableBakes, per entity: what drawing it far saves, and the index of the bake it
    /// uses in baking_ (kNoBake: none). Kept between frames: a frame allocates nothing of them.
    static constexpr std::size_t kNoBake = ~std::size_t(0);
    std::vector<double> savingOf_;
    std::vector<std::size_t> bakeOf_;
    /// Per entity, what drawing its far sprite far costs (BakeCosts::farMs).
    std::vector<double> farMsOf_;
    /// Whether keepAffordableBakes holds the far tier near (its hysteresis state).
    bool farTierHeld_ = false;
    int heldNearCount_ = 0;
    /// beginFrame's count; bakes are paused before frame askAgainAt_ (bakesPaused), after
    /// refusedInARow_ asking frames in a row whose bakes were all given up.
    std::uint64_t frame_ = 0, askAgainAt_ = 0;
    int refusedInARow_ = 0;
};

} // namespace voxtier
