#include "impostor_cache/far_frame.hpp"

#include "core/splitmix64.hpp"
#include "core/stopwatch.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <cstddef>
#include <optional>
#include <tuple>
#include <unordered_map>

namespace voxtier {

namespace {

/// What the cache did for a frame's far tier (bakes, refreshes and the rest), from the counters
/// before and after it.
void addCacheWork(FarFrameStats& stats, const SnapshotCacheCounters& before,
                  const SnapshotCacheCounters& after) {
    stats.bakes += after.bakes - before.bakes;
    stats.scenesBuilt += after.scenesBuilt - before.scenesBuilt;
    stats.refreshes += after.refreshes - before.refreshes;
    stats.incrementalRefreshes += after.incrementalRefreshes - before.incrementalRefreshes;
    stats.cellsRetraced += after.cellsRetraced - before.cellsRetraced;
    stats.raysTraced += after.raysTraced - before.raysTraced;
}

// A snapshot by (model, frame, view, sigma).
using Need = std::tuple<int, int, int, int, int, double>; // model, frame, view x y z, sigma
// Hashed: a crowd of 10^5 sprites shares a few thousand snapshots, and an ordered map's
// lookups were a visible share of the far tier's per-sprite cost there.
struct NeedHash {
    std::size_t operator()(const Need& n) const {
        const auto [m, f, x, y, z, sigma] = n;
        const auto mix = [](std::uint64_t v) { return SplitMix64{v}.next(); };
        std::uint64_t h = mix(std::uint64_t(std::uint32_t(m)) << 32 | std::uint32_t(f));
        h = mix(h ^ (std::uint64_t(std::uint32_t(x)) << 32 | std::uint32_t(y)));
        h = mix(h ^ (std::uint64_t(std::uint32_t(z)) << 32 |
                     std::uint32_t(std::hash<double>{}(sigma))));
        return std::size_t(h);
    }
};

/// The distinct snapshots a frame's far sprites show, each looked up (and baked) once, in
/// parallel, then shared by every sprite that shows it.
class SnapshotNeeds {
  public:
    /// The slot of the snapshot the request's sprite shows (its view, or the nearest of `set`),
    /// added if new.
    explicit SnapshotNeeds(int snapshotScale) : scale_(snapshotScale) {}
    std::size_t slotOf(const FarRequest& r, ViewSet set) {
        const SpriteSetup& sp = *r.sprite;
        // Not value_or: its argument, a nearest-view search over the set, would run for every
        // sprite, though the planner gives almost every one its view (this loop over 9,700 far
        // sprites of 100,000 tanks took 3.0-7.8 ms a frame here with that search and emplace's
        // allocations, 1.2-1.4 ms without).
        const glm::ivec3 view = (r.view ? *r.view : viewIdOf(set, chooseFarView(sp, set))).lattice;
        const Need n{sp.model, sp.frame, view.x, view.y, view.z, sp.lattice.sigma * scale_};
        // try_emplace: emplace would allocate a node for every sprite before finding its key.
        auto [it, inserted] = slot_.try_emplace(n, needs_.size());
        if (inserted) needs_.push_back(n);
        return it->second;
    }
    /// Looks up, baking where missing, every snapshot added since the last call.
    void fetchNew(const std::vector<std::shared_ptr<VoxelModel>>& models, SnapshotCache& cache) {
        const std::size_t from = snaps_.size();
        snaps_.resize(needs_.size());
        tbb::parallel_for(from, needs_.size(), [&](std::size_t i) {
            const auto [m, f, x, y, z, sigma] = needs_[i];
            snaps_[i] = cache.get(*models.at(std::size_t(m)), f, ViewId{{x, y, z}}, sigma);
        });
    }
    std::size_t size() const { return needs_.size(); }
    const Need& need(std::size_t i) const { return needs_[i]; }
    const std::shared_ptr<const Snapshot>& snapshot(std::size_t i) const { return snaps_[i]; }

  private:
    double scale_ = 1.0;
    std::unordered_map<Need, std::size_t, NeedHash> slot_;
    std::vector<Need> needs_;
    std::vector<std::shared_ptr<const Snapshot>> snaps_;
};

} // namespace

void drawFarSprites(const std::vector<std::shared_ptr<VoxelModel>>& models,
                    std::span<const FarRequest> requests, SnapshotCache& cache, ViewSet set,
                    Image& target, FarFrameStats* stats, const FarBlitOptions& blitOptions) {
    const SnapshotCacheCounters before = cache.counters();
    std::vector<const SpriteSetup*> sprites(requests.size());
    for (std::size_t r = 0; r < requests.size(); ++r) sprites[r] = requests[r].sprite;
    // With culling: front to back, in runs, each run's sprites tested whole against what the runs
    // before drew, so a hidden sprite is dropped before its snapshot is looked up or baked.
    const bool cull = blitOptions.occlusionCull;
    const std::vector<std::uint32_t> order = drawOrder(sprites, cull);
    std::optional<OcclusionTiles> tiles;
    if (cull) tiles.emplace(target);

    SnapshotNeeds needs(cache.snapshotScale());
    std::uint64_t drawnSprites = 0;
    double ensureMs = 0.0;
    FarBlitStats blit;
    std::vector<std::size_t> runSlots;
    std::vector<FarSprite> draws;
    const std::size_t culled = drawFrontToBack(
        order, sprites, tiles ? &*tiles : nullptr, occlusionRunPixels(target.pixelCount()),
        [&](std::span<const std::uint32_t> run) {
            const auto t0 = std::chrono::steady_clock::now();
            runSlots.clear();
            for (const std::uint32_t r : run) runSlots.push_back(needs.slotOf(requests[r], set));
            needs.fetchNew(models, cache);
            ensureMs += msSince(t0);
            draws.clear();
            for (std::size_t k = 0; k < run.size(); ++k) {
                const SpriteSetup* sp = sprites[run[k]];
                draws.push_back({sp, needs.snapshot(runSlots[k]).get(),
                                 &models.at(std::size_t(sp->model))->palette()});
            }
            drawnSprites += draws.size();
            blitFar(draws, target, &blit, blitOptions, tiles ? &*tiles : nullptr);
        });
    if (stats) {
        stats->sprites += drawnSprites;
        stats->culled += culled;
        stats->snapshotsUsed += needs.size();
        addCacheWork(*stats, before, cache.counters());
        stats->ensureMs += ensureMs;
        stats->blit.sprites += blit.sprites;
        stats->blit.pixelsTested += blit.pixelsTested;
        stats->blit.pixelsWritten += blit.pixelsWritten;
        stats->blit.partsCulled += blit.partsCulled;
        stats->blit.milliseconds += blit.milliseconds;
    }
}

FarBatch prepareFarBatch(const std::vector<std::shared_ptr<VoxelModel>>& models,
                         std::span<const FarRequest> requests, SnapshotCache& cache, ViewSet set,
                         FarFrameStats* stats) {
    static_assert(far_cell::kEmpty == snapshot_code::kEmpty &&
                  far_cell::kSolid0 == snapshot_code::kSolid0 &&
                  far_cell::kOutline == snapshot_code::kOutline);
    static_assert(sizeof(SnapshotCell) == 2 && offsetof(SnapshotCell, code) == 1);
    const SnapshotCacheCounters before = cache.counters();
    const auto t0 = std::chrono::steady_clock::now();
    SnapshotNeeds needs(cache.snapshotScale());
    std::vector<std::uint32_t> slotOf;
    std::vector<const SpriteSetup*> drawn;
    for (const FarRequest& r : requests) {
        if (!r.sprite || !r.sprite->visible()) continue;
        slotOf.push_back(std::uint32_t(needs.slotOf(r, set)));
        drawn.push_back(r.sprite);
    }
    needs.fetchNew(models, cache);
    FarBatch batch;
    batch.snapshots.reserve(needs.size());
    for (std::size_t i = 0; i < needs.size(); ++i) {
        const auto [m, f, x, y, z, sigma] = needs.need(i);
        const std::shared_ptr<const Snapshot>& snap = needs.snapshot(i);
        // Every version of this view of this model frame shares a lineage: the need with the
        // model's uid in place of its index (a collision only costs a row comparison).
        const std::uint64_t uid = models.at(std::size_t(m))->uid();
        const std::uint64_t lineage = NeedHash{}(Need{int(uid ^ (uid >> 32)), f, x, y, z, sigma});
        batch.snapshots.push_back({snap, lineage | 1u,
                                   reinterpret_cast<const std::uint8_t*>(snap->cells.data()),
                                   snap->lattice.cellRange});
    }
    // Each instance's cell map (in double) on every core, as a frame's other per-sprite loops
    // are: ~10,000 far sprites at 100,000 tanks. Same instances, same order.
    batch.instances.resize(drawn.size());
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, drawn.size(), 256),
                      [&](const tbb::blocked_range<std::size_t>& range) {
                          for (std::size_t k = range.begin(); k != range.end(); ++k) {
                              const SpriteSetup& sp = *drawn[k];
                              const SnapshotCellMap m =
                                  snapshotCellMap(sp.lattice, needs.snapshot(slotOf[k])->lattice);
                              batch.instances[k] = {
                                  &sp,  slotOf[k], &models.at(std::size_t(sp.model))->palette(),
                                  m.u0, m.ui,      m.uj,
                                  m.v0, m.vi,      m.vj};
                          }
                      });
    if (stats) {
        stats->sprites += drawn.size();
        stats->snapshotsUsed += needs.size();
        addCacheWork(*stats, before, cache.counters());
        stats->ensureMs += msSince(t0);
    }
    return batch;
}

} // namespace voxtier
