#include "lod/error_budget.hpp"

#include "core/splitmix64.hpp"
#include "core/sprite.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <bit>

namespace voxtier {

namespace {

/// Budget units per virtual pixel of a sprite whose virtual pixel spans `cellSizePx` pixels.
double unitsPerVpx(double cellSizePx) {
    return std::min(1.0, cellSizePx);
}

} // namespace

double budgetUnitsPerVpx(const SpriteSetup& sprite) {
    return unitsPerVpx(cellSizePx(sprite));
}

namespace {

/// predictedBudgetUnits of one sprite against several views, what the sprite fixes computed once
/// (DisplacementPredictor): the level scan predicts up to seven views per entity.
class BudgetPredictor {
  public:
    explicit BudgetPredictor(const SpriteSelectionInputs& in)
        : displacement_(in.displacement), unitsPerVpx_(unitsPerVpx(in.cellSizePx)) {}
    /// The prediction for the view whose unit vector is `w`.
    double operator()(glm::dvec3 w) const { return displacement_.vpx(w) * unitsPerVpx_; }

  private:
    DisplacementPredictor displacement_;
    double unitsPerVpx_;
};

} // namespace

double predictedBudgetUnits(const SpriteSetup& sprite, ViewId view) {
    return predictedBudgetUnits(selectionInputs(sprite), view);
}

double predictedBudgetUnits(const SpriteSelectionInputs& sprite, ViewId view) {
    return predictedBudgetUnits(sprite, viewDirection(view));
}

double predictedBudgetUnits(const SpriteSelectionInputs& sprite, glm::dvec3 direction) {
    return BudgetPredictor(sprite)(direction);
}

double bestBudgetUnits(const SpriteSetup& sprite, const SelectorConfig& config) {
    return bestBudgetUnits(selectionInputs(sprite), config);
}

double bestBudgetUnits(const SpriteSelectionInputs& sprite, const SelectorConfig& config) {
    return BudgetPredictor(sprite)(
        nearestDirectedLadderView(config.ladderCap, sprite.towardViewer).direction);
}

namespace {
/// 4 MB: a moving 100,000-tank army asks about 20,000-30,000 snapshots a frame, and answers kept
/// across frames fill it by ~1,500 new questions a frame until it is half full.
constexpr std::size_t kAnswerSlots = std::size_t(1) << 17;
constexpr int kMaxProbes = 64;
/// A slot's state word: its generation above, and below it one of these. kForgotten: the
/// question is here, its answer to be asked again (its snapshot changed since).
enum : std::uint32_t { kForgotten = 0, kAsking = 1, kNotCached = 2, kCached = 3 };

/// Where a question's probes start. Not by sigma: the snapshots that changed are named without
/// it (CachedView), so that every sigma's question about them is found where they start.
std::uint64_t placeOf(int model, int frame, glm::ivec3 l) {
    const std::uint64_t h =
        splitmix64Mix(std::uint64_t(std::uint32_t(model)) << 32 | std::uint32_t(frame));
    return splitmix64Mix(h ^ (std::uint64_t(std::uint32_t(l.x)) << 42 ^
                              std::uint64_t(std::uint32_t(l.y)) << 21 ^ std::uint32_t(l.z)));
}
} // namespace

struct SharedCacheAnswers::Slot {
    std::atomic<std::uint32_t> state{0}; ///< generation << 2 | kForgotten / kAsking / ...
    int model = 0, frame = 0;
    glm::ivec3 view{0};
    double sigma = 0.0; ///< written before the state's release, read after its acquire
};

SharedCacheAnswers::SharedCacheAnswers() = default;
SharedCacheAnswers::~SharedCacheAnswers() = default;

void SharedCacheAnswers::begin() {
    if (!slots_) slots_ = std::make_unique<Slot[]>(kAnswerSlots);
    if (++generation_ >= (1u << 30)) { // the state word's generation would wrap: empty them all
        for (std::size_t k = 0; k < kAnswerSlots; ++k) slots_[k].state.store(0);
        generation_ = 1;
    }
    used_ = 0;
    asked_ = 0;
}

void SharedCacheAnswers::beginKeeping(std::span<const CachedView> changed) {
    if (!slots_ || used_ > kAnswerSlots / 2) return begin();
    asked_ = 0;
    const std::uint32_t g = generation_;
    for (const CachedView& c : changed) {
        // A question is never placed past the first slot still empty from where its probes start
        // (slots are not emptied within a generation), nor past kMaxProbes.
        const std::uint64_t h = placeOf(c.model, c.frame, c.view.lattice);
        for (int probe = 0; probe < kMaxProbes; ++probe) {
            Slot& s = slots_[(h + std::uint64_t(probe)) & (kAnswerSlots - 1)];
            if (s.state.load(std::memory_order_relaxed) >> 2 != g) break;
            if (s.model == c.model && s.frame == c.frame && s.view == c.view.lattice)
                s.state.store(g << 2 | kForgotten, std::memory_order_relaxed);
        }
    }
}

bool SharedCacheAnswers::ask(const SpriteSetup& sprite, ViewId view,
                             const std::function<bool(const SpriteSetup&, ViewId)>& isCached) {
    if (!slots_) return isCached(sprite, view);
    const glm::ivec3 l = view.lattice;
    const std::uint64_t h = placeOf(sprite.model, sprite.frame, l);
    const std::uint32_t g = generation_;
    // The slot is this thread's (kAsking): the cache's answer goes in it.
    const auto answer = [&](Slot& s) {
        asked_.fetch_add(1, std::memory_order_relaxed);
        const bool cached = isCached(sprite, view);
        s.state.store(g << 2 | (cached ? kCached : kNotCached), std::memory_order_release);
        return cached;
    };
    for (int probe = 0; probe < kMaxProbes; ++probe) {
        Slot& s = slots_[(h + std::uint64_t(probe)) & (kAnswerSlots - 1)];
        std::uint32_t st = s.state.load(std::memory_order_acquire);
        for (;;) {
            if (st >> 2 != g) {
                // Empty this generation: claim it and ask (or, if another thread claimed it
                // first, read on: st holds its state).
                if (s.state.compare_exchange_strong(st, g << 2 | kAsking,
                                                    std::memory_order_acquire)) {
                    s.model = sprite.model, s.frame = sprite.frame, s.view = l;
                    s.sigma = sprite.lattice.sigma;
                    used_.fetch_add(1, std::memory_order_relaxed);
                    return answer(s);
                }
                continue;
            }
            while ((st & 3u) == kAsking) st = s.state.load(std::memory_order_acquire);
            if (s.model != sprite.model || s.frame != sprite.frame || s.view != l ||
                s.sigma != sprite.lattice.sigma)
                break; // another question: the next slot
            if ((st & 3u) != kForgotten) return (st & 3u) == kCached;
            // Forgotten since it was answered: asked again by the thread that claims it back.
            if (s.state.compare_exchange_strong(st, g << 2 | kAsking, std::memory_order_acquire))
                return answer(s);
        }
    }
    asked_.fetch_add(1, std::memory_order_relaxed);
    return isCached(sprite, view);
}

double BakeCosts::nearMs(const SpriteSetup& sprite) const {
    return nearCostUnits(sprite, nearRate) * nearMsPerUnit;
}

double BakeCosts::farMs(const SpriteSetup& sprite) const {
    return double(rectPixels(sprite)) * blitMsPerPx;
}

double BakeCosts::nearMs(const SpriteSelectionInputs& sprite) const {
    return nearCostUnits(sprite.cells, sprite.rectPixels, nearRate) * nearMsPerUnit;
}

double BakeCosts::farMs(const SpriteSelectionInputs& sprite) const {
    return double(sprite.rectPixels) * blitMsPerPx;
}

double BakeCosts::farSavingMs(const SpriteSetup& sprite) const {
    return nearMs(sprite) - farMs(sprite);
}

std::size_t ErrorBudgetViews::BakeTable::hash(const BakeKey& key) {
    // The answers' placement of the snapshot, with the sigma the answers leave out.
    return std::size_t(splitmix64Mix(placeOf(key.model, key.frame, key.view.lattice) ^
                                     std::bit_cast<std::uint64_t>(key.sigma)));
}

void ErrorBudgetViews::BakeTable::clear() {
    if (used_ == 0) return;
    for (Slot& slot : slots_) slot.index = kNone;
    used_ = 0;
}

std::size_t ErrorBudgetViews::BakeTable::find(const BakeKey& key) const {
    if (used_ == 0) return kNone;
    const std::size_t mask = slots_.size() - 1;
    for (std::size_t at = hash(key) & mask;; at = (at + 1) & mask) {
        const Slot& slot = slots_[at];
        if (slot.index == kNone) return kNone; // never full: at most half
        if (slot.key == key) return slot.index;
    }
}

void ErrorBudgetViews::BakeTable::insert(const BakeKey& key, std::size_t index) {
    if (2 * (used_ + 1) > slots_.size()) {
        // Twice the size, every key placed again.
        std::vector<Slot> old = std::move(slots_);
        slots_.assign(std::max<std::size_t>(64, 2 * old.size()), Slot{});
        used_ = 0;
        for (const Slot& slot : old)
            if (slot.index != kNone) insert(slot.key, slot.index);
    }
    const std::size_t mask = slots_.size() - 1;
    std::size_t at = hash(key) & mask;
    while (slots_[at].index != kNone) at = (at + 1) & mask;
    slots_[at] = {key, index};
    ++used_;
}

void ErrorBudgetViews::beginFrame(std::size_t entities, int bakes) {
    current_.resize(entities);
    fades_.resize(entities);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, fades_.size(), 4096), [&](const auto& r) {
        for (std::size_t i = r.begin(); i != r.end(); ++i)
            if (fades_[i].left > 0) --fades_[i].left;
    });
    baking_.clear();
    bakingIndex_.clear();
    bakesLeft_ = bakes;
    viewChanges_ = 0;
    ++frame_;
}

void ErrorBudgetViews::drop(std::size_t entity) {
    if (entity < current_.size()) current_[entity].reset(), fades_[entity].left = 0;
}

bool ErrorBudgetViews::viewFade(std::size_t entity, const SpriteSetup& sprite,
                                const SelectorConfig& config, const IsCached& isCached,
                                float* share, ViewId* from) {
    return viewFade(entity, sprite, selectionInputs(sprite), config, isCached, share, from);
}

bool ErrorBudgetViews::viewFade(std::size_t entity, const SpriteSetup& sprite,
                                const SpriteSelectionInputs& selection,
                                const SelectorConfig& config, const IsCached& isCached,
                                float* share, ViewId* from) {
    Fade& f = fades_.at(entity);
    if (f.left <= 0) return false;
    if (predictedBudgetUnits(selection, f.from) > config.budgetVpx || !isCached(sprite, f.from)) {
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
                                               const IsCached& isCached,
                                               const IsCached& withoutBake) {
    return choose(entity, sprite, config, prepare(entity, sprite, config, isCached), withoutBake);
}

namespace {

/// ErrorBudgetViews::LevelScan of `sprite`. The levels' nearest views within the budget, coarse
/// to fine: a fresh choice aims at far_at's share of the budget where it can, so the next small
/// move does not switch again; a snapshot already cached (in memory or on disk) wins over one
/// that needs a bake. A level's view and prediction are computed only when the scan reaches it
/// (a scan that stops at a coarse level never looks up the finer ones), and each level is met
/// once: the first target's levels are within the second's, so meeting them again in the same
/// order changes neither the first cached view nor the first of the others.
ErrorBudgetViews::LevelScan scanLevels(const SpriteSetup& sprite,
                                       const SpriteSelectionInputs& selection,
                                       const SelectorConfig& config,
                                       const ErrorBudgetViews::IsCached& isCached) {
    ErrorBudgetViews::LevelScan scan;
    const double budget = config.budgetVpx;
    std::size_t count = 0;
    while (count < kViewLadder.size() && kViewLadder[count] <= config.ladderCap) ++count;
    std::array<std::optional<double>, kViewLadder.size()> predicted;
    std::array<ViewId, kViewLadder.size()> views;
    std::array<bool, kViewLadder.size()> met{};
    const BudgetPredictor predict(selection);
    const double targets[2] = {budget * std::min(1.0, config.farAt / config.nearAt), budget};
    for (const double target : targets)
        for (std::size_t k = 0; k < count; ++k) {
            if (!predicted[k]) {
                const DirectedView v =
                    nearestDirectedLadderView(kViewLadder[k], selection.towardViewer);
                views[k] = v.id;
                predicted[k] = predict(v.direction);
            }
            if (*predicted[k] > target || met[k]) continue;
            met[k] = true;
            if (isCached(sprite, views[k])) {
                scan.cachedPick = views[k];
                return scan;
            }
            scan.met[std::size_t(scan.metCount++)] = views[k];
        }
    return scan;
}

} // namespace

ErrorBudgetViews::Prepared ErrorBudgetViews::prepare(std::size_t entity, const SpriteSetup& sprite,
                                                     const SelectorConfig& config,
                                                     const IsCached& isCached) const {
    return prepare(entity, sprite, selectionInputs(sprite), config, isCached);
}

ErrorBudgetViews::Prepared ErrorBudgetViews::prepare(std::size_t entity, const SpriteSetup& sprite,
                                                     const SpriteSelectionInputs& selection,
                                                     const SelectorConfig& config,
                                                     const IsCached& isCached) const {
    Prepared p;
    const std::optional<ViewId>& current = current_.at(entity);
    p.currentUnits = current ? predictedBudgetUnits(selection, *current) : 0.0;
    p.currentWithin = current && p.currentUnits <= config.budgetVpx;
    p.currentCached = p.currentWithin && isCached(sprite, *current);
    // A current view within the budget and cached is kept: no scan. Else choose() reads the
    // scan where the current view is not within the budget, and where it is but needs a bake that
    // neither another entity nor the bound gives it; which of those it is only the serial pass
    // knows, so every such entity is scanned here, on every core (at 100,000 tanks under the
    // error budget ~5,000 entities a frame wait for a bake, and the serial pass scanned most of
    // them once the bound was spent).
    if (!p.settled() && !bakesPaused()) p.scan = scanLevels(sprite, selection, config, isCached);
    return p;
}

std::optional<ViewId> ErrorBudgetViews::choose(std::size_t entity, const SpriteSetup& sprite,
                                               const SelectorConfig& config,
                                               const Prepared& prepared,
                                               const IsCached& withoutBake) {
    std::optional<ViewId>& current = current_.at(entity);
    if (waitsOutThePause(entity, prepared)) return std::nullopt;
    const auto baking = [&](ViewId v) {
        return bakingIndex_.find(keyOf(sprite, v)) != BakeTable::kNone;
    };
    const auto onDisk = [&](ViewId v) { return withoutBake && withoutBake(sprite, v); };
    const auto bake = [&](ViewId v) {
        if (baking(v)) return v; // another entity's bake this frame: no second one
        --bakesLeft_;
        baking_.push_back(keyOf(sprite, v));
        bakingIndex_.insert(baking_.back(), baking_.size() - 1);
        return v;
    };
    // Hysteresis on the view and level: a view within the budget is kept however the camera
    // wobbles, even when a coarser level would do now. An animated model may need it baked for
    // its new frame: that counts against the bound like any bake.
    if (prepared.currentWithin) {
        if (prepared.currentCached || baking(*current) || onDisk(*current)) return current;
        if (bakesLeft_ > 0) return bake(*current);
    }
    const LevelScan& scan = prepared.scan;
    // No cached view within the budget: the first the scan met needs a bake, unless another
    // entity bakes one of them this frame. A view another entity bakes is not preferred to the
    // coarsest one (so that a frame picks the same views whether its snapshots were baked before
    // or are baked now: a pre-baked directory gives the cold image), only taken when the bake
    // bound is spent.
    std::optional<ViewId> pick = scan.cachedPick, pickNeedingBake, pickBaking;
    if (!pick)
        for (int k = 0; k < scan.metCount; ++k) {
            const ViewId v = scan.met[std::size_t(k)];
            if (!pickNeedingBake) pickNeedingBake = v;
            if (!pickBaking && baking(v)) pickBaking = v;
        }
    // The view a bake would be for, read from disk instead when a file has it: the same view
    // either way, only the bake is spared.
    if (!pick && pickNeedingBake && onDisk(*pickNeedingBake)) pick = pickNeedingBake;
    if (!pick && pickNeedingBake && (bakesLeft_ > 0 || baking(*pickNeedingBake)))
        pick = bake(*pickNeedingBake);
    if (!pick) pick = pickBaking;
    if (pick && current && !(*pick == *current)) {
        // Entities past the spent bake bound choose on every core (FramePlanner::plan).
        std::atomic_ref<int>(viewChanges_).fetch_add(1, std::memory_order_relaxed);
        if (config.crossfadeFrames > 0) fades_.at(entity) = {*current, config.crossfadeFrames};
    }
    current = pick;
    return pick;
}

bool ErrorBudgetViews::waitsOutThePause(std::size_t entity, const Prepared& prepared) {
    if (!bakesPaused() || prepared.settled()) return false;
    drop(entity);
    return true;
}

bool ErrorBudgetViews::weighFarTier(double farMs, double nearMs) {
    farTierHeld_ = farTierHeld_ ? farMs >= kLetGoBelow * nearMs : farMs > kHoldNearAbove * nearMs;
    return farTierHeld_;
}

std::vector<std::size_t> ErrorBudgetViews::keepAffordableBakes(
    std::span<const SpriteSetup> sprites, const std::vector<std::optional<ViewId>>& drawnFrom,
    const BakeCosts& costs, std::span<const std::uint8_t> mayUseABake,
    std::span<const SpriteSelectionInputs> selection) {
    std::vector<std::size_t> givenUp;
    heldNearCount_ = 0;
    // A frame that asks for no bake outside a pause ends a run of refusals (bakesPaused).
    if (baking_.empty() && !bakesPaused()) refusedInARow_ = 0;
    // Nothing to weigh: no bake, and no blit measured for the far tier's own cost.
    if (!costs.known() || (baking_.empty() && !(costs.blitMsPerPx > 0.0))) return givenUp;
    // What each far sprite saves, costs far and which bake it uses, found in parallel (each
    // sprite read is a cache miss: 4-5 ms of every frame at 100,000 tanks on one core; its sizes
    // are read from its selection inputs where given, in order), then summed in entity order as
    // one walk would: the same sums, whatever the threads.
    const std::size_t n = std::min(sprites.size(), drawnFrom.size());
    const bool sized = selection.size() >= n;
    const auto farMsOf = [&](std::size_t i) {
        return sized ? costs.farMs(selection[i]) : costs.farMs(sprites[i]);
    };
    const auto nearMsOf = [&](std::size_t i) {
        return sized ? costs.nearMs(selection[i]) : costs.nearMs(sprites[i]);
    };
    if (baking_.empty()) {
        // No bake to weigh (a still camera's frames, once the cache holds their views): only the
        // tier, summed on every core with nothing written per entity. Every view drawn is
        // cached, so a held tier keeps them all.
        const TierMs tier = sumTierMs(n, [&](std::size_t i) {
            return drawnFrom[i] ? TierMs{farMsOf(i), nearMsOf(i), 1} : TierMs{};
        });
        if (!weighFarTier(tier.far, tier.near)) return givenUp;
        for (std::size_t i = 0; i < n; ++i)
            if (drawnFrom[i]) givenUp.push_back(i);
        heldNearCount_ = int(givenUp.size());
        return givenUp;
    }
    savingOf_.resize(n);
    farMsOf_.resize(n);
    bakeOf_.resize(n);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 1024), [&](const auto& r) {
        for (std::size_t i = r.begin(); i != r.end(); ++i) {
            if (!drawnFrom[i]) continue;
            farMsOf_[i] = farMsOf(i);
            savingOf_[i] = nearMsOf(i) - farMsOf_[i];
            // Most far entities keep a cached view: no hash lookup for them (under the error
            // budget at 100,000 tanks, ~50,000 of ~70,000 lookups a frame).
            if (!mayUseABake.empty() && !mayUseABake[i]) {
                bakeOf_[i] = kNoBake;
                continue;
            }
            const std::size_t b = bakingIndex_.find(keyOf(sprites[i], *drawnFrom[i]));
            bakeOf_[i] = b == BakeTable::kNone ? kNoBake : b;
        }
    });
    // What each bake's users save, and what every far sprite saves (cached views included: the
    // sprites already far pay for the bakes of the frame, so the frame is never slower than
    // drawing them all near, as far as the measured costs tell).
    std::vector<double> saving(baking_.size(), 0.0);
    std::vector<std::vector<std::size_t>> users(baking_.size());
    double savedMs = 0.0, farMs = 0.0;
    for (std::size_t i = 0; i < n; ++i) {
        if (!drawnFrom[i]) continue;
        savedMs += savingOf_[i];
        farMs += farMsOf_[i];
        if (bakeOf_[i] == kNoBake) continue;
        saving[bakeOf_[i]] += savingOf_[i];
        users[bakeOf_[i]].push_back(i);
    }
    // The far tier as a whole: the blit's measured rate holds the tier's fixed part (a pass over
    // the image, a dispatch), so one sprite weighed alone looks dearer far than it is, the more so
    // the fewer pixels the tier has; summed over the tier, the rate gives what the tier cost.
    if (weighFarTier(farMs, savedMs + farMs)) {
        std::vector<std::size_t> nearInstead;
        for (std::size_t i = 0; i < n; ++i)
            if (drawnFrom[i]) {
                nearInstead.push_back(i);
                if (bakeOf_[i] != kNoBake) drop(i); // a view to be baked: scanned afresh
            }
        heldNearCount_ = int(nearInstead.size());
        bakesLeft_ += int(baking_.size());
        baking_.clear();
        bakingIndex_.clear();
        return nearInstead;
    }
    std::vector<std::size_t> order(baking_.size());
    for (std::size_t k = 0; k < order.size(); ++k) order[k] = k;
    std::stable_sort(order.begin(), order.end(),
                     [&](std::size_t a, std::size_t b) { return saving[a] < saving[b]; });
    double bakeMs = double(baking_.size()) * costs.msPerBake + costs.planMs;
    std::vector<bool> dropped(baking_.size(), false);
    // Giving up a bake that saves at least its cost would not bring the frame nearer the bound.
    for (std::size_t k : order) {
        if (bakeMs <= savedMs || saving[k] >= costs.msPerBake) break;
        dropped[k] = true;
        bakeMs -= costs.msPerBake;
        savedMs -= saving[k];
        ++bakesLeft_;
        for (std::size_t i : users[k]) givenUp.push_back(i);
    }
    std::vector<BakeKey> kept;
    bakingIndex_.clear();
    for (std::size_t k = 0; k < baking_.size(); ++k)
        if (!dropped[k]) {
            kept.push_back(baking_[k]);
            bakingIndex_.insert(kept.back(), kept.size() - 1);
        }
    // Every bake given up: the next frames would ask for the same ones (bakesPaused).
    if (kept.empty()) {
        refusedInARow_ = std::min(refusedInARow_ + 1, kRefusalsCounted);
        askAgainAt_ = frame_ + (std::uint64_t(1) << refusedInARow_);
    } else {
        refusedInARow_ = 0;
        askAgainAt_ = 0;
    }
    baking_ = std::move(kept);
    std::sort(givenUp.begin(), givenUp.end());
    for (std::size_t i : givenUp) drop(i);
    return givenUp;
}

} // namespace voxtier
