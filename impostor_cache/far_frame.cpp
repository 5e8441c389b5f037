#include "impostor_cache/far_frame.hpp"

#include "core/splitmix64.hpp"
#include "core/stopwatch.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstddef>
#include <memory>
#include <optional>
#include <stdexcept>
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

/// The snapshot a far request's (visible) sprite shows: its view (the planner's, or the nearest
/// of `set`) at the sprite's sigma times the cache's snapshot scale.
Need needOf(const FarRequest& r, ViewSet set, double snapshotScale) {
    const SpriteSetup& sp = *r.sprite;
    // Not value_or: its argument, a nearest-view search over the set, would run for every
    // sprite, though the planner gives almost every one its view (a loop over 9,700 far sprites of
    // 100,000 tanks took 3.0-7.8 ms a frame here with that search and emplace's allocations,
    // 1.2-1.4 ms without).
    const glm::ivec3 view = (r.view ? *r.view : viewIdOf(set, chooseFarView(sp, set))).lattice;
    return {sp.model, sp.frame, view.x, view.y, view.z, sp.lattice.sigma * snapshotScale};
}

/// What SnapshotCache::get is asked for `need`.
SnapshotCache::Ask askOf(const Need& need, const std::vector<std::shared_ptr<VoxelModel>>& models) {
    const auto [m, f, x, y, z, sigma] = need;
    return {models.at(std::size_t(m)).get(), f, ViewId{{x, y, z}}, sigma};
}

/// The distinct snapshots a frame's far sprites show, each looked up (and baked) once, in
/// parallel, then shared by every sprite that shows it.
class SnapshotNeeds {
  public:
    /// The slot of the snapshot the request's sprite shows (its view, or the nearest of `set`),
    /// added if new.
    explicit SnapshotNeeds(int snapshotScale) : scale_(snapshotScale) {}
    std::size_t slotOf(const FarRequest& r, ViewSet set) {
        const Need n = needOf(r, set, scale_);
        // try_emplace: emplace would allocate a node for every sprite before finding its key.
        auto [it, inserted] = slot_.try_emplace(n, needs_.size());
        if (inserted) needs_.push_back(n);
        return it->second;
    }
    /// Looks up, baking where missing, every snapshot added since the last call (the cached ones
    /// under one lock: SnapshotCache::getAll).
    void fetchNew(const std::vector<std::shared_ptr<VoxelModel>>& models, SnapshotCache& cache) {
        const std::size_t from = snaps_.size();
        asks_.resize(needs_.size() - from);
        for (std::size_t i = from; i < needs_.size(); ++i)
            asks_[i - from] = askOf(needs_[i], models);
        snaps_.resize(needs_.size());
        cache.getAll(asks_, std::span(snaps_).subspan(from));
    }
    std::size_t size() const { return needs_.size(); }
    const Need& need(std::size_t i) const { return needs_[i]; }
    const std::shared_ptr<const Snapshot>& snapshot(std::size_t i) const { return snaps_[i]; }

  private:
    double scale_ = 1.0;
    std::unordered_map<Need, std::size_t, NeedHash> slot_;
    std::vector<Need> needs_;
    std::vector<SnapshotCache::Ask> asks_; ///< fetchNew's
    std::vector<std::shared_ptr<const Snapshot>> snaps_;
};

/// The statistics of a far frame's blit and the sprites it drew, added to `stats`.
void addBlit(FarFrameStats& stats, const FarBlitStats& blit) {
    stats.blit.sprites += blit.sprites;
    stats.blit.pixelsTested += blit.pixelsTested;
    stats.blit.pixelsWritten += blit.pixelsWritten;
    stats.blit.partsCulled += blit.partsCulled;
    stats.blit.milliseconds += blit.milliseconds;
}

} // namespace

FarDraws fetchFarSnapshots(const std::vector<std::shared_ptr<VoxelModel>>& models,
                           std::span<const FarRequest> requests, SnapshotCache& cache,
                           ViewSet set) {
    const auto t0 = std::chrono::steady_clock::now();
    FarDraws draws;
    draws.cacheBefore = cache.counters();
    std::vector<const SpriteSetup*> sprites(requests.size());
    for (std::size_t r = 0; r < requests.size(); ++r) sprites[r] = requests[r].sprite;
    // drawFarSprites' order and lookups without culling: one run of every visible sprite.
    const std::vector<std::uint32_t> order = drawOrder(sprites, false);
    SnapshotNeeds needs(cache.snapshotScale());
    std::vector<std::size_t> slots;
    slots.reserve(order.size());
    for (const std::uint32_t r : order) slots.push_back(needs.slotOf(requests[r], set));
    needs.fetchNew(models, cache);
    draws.sprites.reserve(order.size());
    for (std::size_t k = 0; k < order.size(); ++k) {
        const SpriteSetup* sp = sprites[order[k]];
        draws.sprites.push_back(
            {sp, needs.snapshot(slots[k]).get(), &models.at(std::size_t(sp->model))->palette()});
    }
    draws.held.reserve(needs.size());
    for (std::size_t i = 0; i < needs.size(); ++i) draws.held.push_back(needs.snapshot(i));
    draws.cacheAfter = cache.counters();
    draws.ensureMs = msSince(t0);
    return draws;
}

void blitFarDraws(const FarDraws& draws, Image& target, FarFrameStats* stats,
                  const FarBlitOptions& blitOptions) {
    if (blitOptions.occlusionCull)
        throw std::invalid_argument("blitFarDraws: occlusion culling draws in runs, a run at a "
                                    "time (drawFarSprites)");
    FarBlitStats blit;
    blitFar(draws.sprites, target, &blit, blitOptions);
    if (!stats) return;
    // As drawFarSprites counts a frame: its sprites, snapshots, the cache's work and both times.
    stats->sprites += draws.sprites.size();
    stats->snapshotsUsed += draws.held.size();
    addCacheWork(*stats, draws.cacheBefore, draws.cacheAfter);
    stats->ensureMs += draws.ensureMs;
    addBlit(*stats, blit);
}

void drawFarSprites(const std::vector<std::shared_ptr<VoxelModel>>& models,
                    std::span<const FarRequest> requests, SnapshotCache& cache, ViewSet set,
                    Image& target, FarFrameStats* stats, const FarBlitOptions& blitOptions) {
    if (!blitOptions.occlusionCull) {
        blitFarDraws(fetchFarSnapshots(models, requests, cache, set), target, stats, blitOptions);
        return;
    }
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
        addBlit(*stats, blit);
    }
}

FarBatch prepareFarBatch(const std::vector<std::shared_ptr<VoxelModel>>& models,
                         std::span<const FarRequest> requests, SnapshotCache& cache, ViewSet set,
                         FarFrameStats* stats) {
    FarBatch batch;
    FarBatchScratch scratch;
    prepareFarBatch(models, requests, cache, set, batch, scratch, stats);
    return batch;
}

struct FarBatchScratch::Impl {
    static constexpr std::uint32_t kHidden = ~0u; ///< places[k] of a request drawing nothing
    std::vector<Need> keys;                       ///< per request, its snapshot (if drawn)
    std::vector<std::uint64_t> hashes;            ///< NeedHash of keys[k]
    std::vector<std::uint32_t> places;            ///< per request, its table position or kHidden
    std::vector<std::uint32_t> drawnBefore, firstsBefore; ///< per chunk of requests
    std::vector<std::uint32_t> needFirst; ///< per distinct snapshot, the first request showing it
    std::vector<std::uint32_t> needAt;    ///< per table position claimed this frame, its snapshot
    /// Open addressing over the distinct snapshots: generation << 32 | (least request + 1), a
    /// position of another generation empty (nothing cleared between frames).
    std::unique_ptr<std::atomic<std::uint64_t>[]> table;
    std::size_t tableSize = 0;
    std::uint32_t generation = 0;
    std::vector<SnapshotCache::Ask> asks;                 ///< per distinct snapshot
    std::vector<std::shared_ptr<const Snapshot>> fetched; ///< moved into the batch
    std::vector<const Snapshot*> snapshots; ///< per distinct snapshot; the batch holds them
};

FarBatchScratch::FarBatchScratch() : impl_(std::make_unique<Impl>()) {}
FarBatchScratch::~FarBatchScratch() = default;
FarBatchScratch::FarBatchScratch(FarBatchScratch&&) noexcept = default;
FarBatchScratch& FarBatchScratch::operator=(FarBatchScratch&&) noexcept = default;

void prepareFarBatch(const std::vector<std::shared_ptr<VoxelModel>>& models,
                     std::span<const FarRequest> requests, SnapshotCache& cache, ViewSet set,
                     FarBatch& batch, FarBatchScratch& scratch, FarFrameStats* stats) {
    static_assert(far_cell::kEmpty == snapshot_code::kEmpty &&
                  far_cell::kSolid0 == snapshot_code::kSolid0 &&
                  far_cell::kOutline == snapshot_code::kOutline);
    static_assert(sizeof(SnapshotCell) == 2 && offsetof(SnapshotCell, code) == 1);
    const SnapshotCacheCounters before = cache.counters();
    const auto t0 = std::chrono::steady_clock::now();
    FarBatchScratch::Impl& w = *scratch.impl_;
    constexpr std::uint32_t kHidden = FarBatchScratch::Impl::kHidden;
    const std::size_t n = requests.size();
    const double scale = cache.snapshotScale();
    // The requests in chunks: each chunk's drawn requests and first showings are counted on
    // every core, then written from the offsets of the chunks before it, so the snapshots and
    // instances come out in the order one core walking the requests gives them.
    constexpr std::size_t kChunk = 4096;
    const std::size_t chunks = (n + kChunk - 1) / kChunk;
    const auto chunkEnd = [&](std::size_t c) { return std::min(n, (c + 1) * kChunk); };
    w.keys.resize(n);
    w.hashes.resize(n);
    w.places.resize(n);
    w.drawnBefore.assign(chunks + 1, 0);
    w.firstsBefore.assign(chunks + 1, 0);
    // 1. Each drawn request's snapshot: its view (the planner's, or the nearest of the set).
    tbb::parallel_for(std::size_t(0), chunks, [&](std::size_t c) {
        std::uint32_t drawn = 0;
        for (std::size_t k = c * kChunk; k != chunkEnd(c); ++k) {
            const FarRequest& r = requests[k];
            if (!r.sprite || !r.sprite->visible()) {
                w.places[k] = kHidden;
                continue;
            }
            w.keys[k] = needOf(r, set, scale);
            w.hashes[k] = NeedHash{}(w.keys[k]);
            w.places[k] = 0;
            ++drawn;
        }
        w.drawnBefore[c + 1] = drawn;
    });
    for (std::size_t c = 0; c < chunks; ++c) w.drawnBefore[c + 1] += w.drawnBefore[c];
    const std::size_t drawn = w.drawnBefore[chunks];
    // 2. Each distinct snapshot's table position, holding the least request that shows it. At
    // most half the table is taken, so every probe ends.
    std::size_t size = 64;
    while (size < 2 * drawn) size *= 2;
    if (size > w.tableSize) {
        w.table = std::make_unique<std::atomic<std::uint64_t>[]>(size); // zero: generation 0
        w.tableSize = size;
        w.generation = 0;
        w.needAt.resize(size);
    }
    if (++w.generation == 0) { // wrapped: positions of an old generation could read as current
        for (std::size_t i = 0; i < w.tableSize; ++i) w.table[i].store(0);
        w.generation = 1;
    }
    const std::uint64_t generation = w.generation;
    const std::size_t mask = w.tableSize - 1;
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 1024), [&](const auto& range) {
        for (std::size_t k = range.begin(); k != range.end(); ++k) {
            if (w.places[k] == kHidden) continue;
            const std::uint64_t mine = generation << 32 | std::uint64_t(k + 1);
            for (std::size_t pos = w.hashes[k] & mask;; pos = (pos + 1) & mask) {
                std::atomic<std::uint64_t>& slot = w.table[pos];
                std::uint64_t held = slot.load(std::memory_order_relaxed);
                if (held >> 32 != generation) {
                    if (slot.compare_exchange_strong(held, mine, std::memory_order_relaxed)) {
                        w.places[k] = std::uint32_t(pos);
                        break;
                    }
                    // Claimed meanwhile: `held` is this frame's now, and read on below.
                }
                // A position claimed this frame keeps its snapshot: compare the keys (all written
                // in step 1); the same one: the least request stays.
                if (!(w.keys[std::uint32_t(held) - 1] == w.keys[k])) continue;
                while (std::uint32_t(held) > k + 1 &&
                       !slot.compare_exchange_weak(held, mine, std::memory_order_relaxed)) {
                }
                w.places[k] = std::uint32_t(pos);
                break;
            }
        }
    });
    // 3. The distinct snapshots in the order of their first showing: each chunk counts the
    // requests that hold their position, then numbers them from the chunks' offsets.
    const auto isFirst = [&](std::size_t k) {
        return w.places[k] != kHidden &&
               std::uint32_t(w.table[w.places[k]].load(std::memory_order_relaxed)) == k + 1;
    };
    tbb::parallel_for(std::size_t(0), chunks, [&](std::size_t c) {
        std::uint32_t firsts = 0;
        for (std::size_t k = c * kChunk; k != chunkEnd(c); ++k) firsts += isFirst(k);
        w.firstsBefore[c + 1] = firsts;
    });
    for (std::size_t c = 0; c < chunks; ++c) w.firstsBefore[c + 1] += w.firstsBefore[c];
    const std::size_t distinct = w.firstsBefore[chunks];
    w.needFirst.resize(distinct);
    tbb::parallel_for(std::size_t(0), chunks, [&](std::size_t c) {
        std::uint32_t next = w.firstsBefore[c];
        for (std::size_t k = c * kChunk; k != chunkEnd(c); ++k)
            if (isFirst(k)) {
                w.needFirst[next] = std::uint32_t(k);
                w.needAt[w.places[k]] = next++;
            }
    });
    // 4. The snapshots: the cached ones under one lock, the others baked in parallel.
    w.asks.resize(distinct);
    w.fetched.resize(distinct);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, distinct, 256), [&](const auto& range) {
        for (std::size_t i = range.begin(); i != range.end(); ++i)
            w.asks[i] = askOf(w.keys[w.needFirst[i]], models);
    });
    cache.getAll(w.asks, w.fetched);
    batch.snapshots.resize(distinct);
    w.snapshots.resize(distinct);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, distinct, 256), [&](const auto& range) {
        for (std::size_t i = range.begin(); i != range.end(); ++i) {
            const auto [m, f, x, y, z, sigma] = w.keys[w.needFirst[i]];
            // Every version of this view of this model frame shares a lineage: the need with
            // the model's uid in place of its index (a collision only costs a row comparison).
            const std::uint64_t uid = models.at(std::size_t(m))->uid();
            const std::uint64_t lineage =
                NeedHash{}(Need{int(uid ^ (uid >> 32)), f, x, y, z, sigma});
            const Snapshot* snap = w.snapshots[i] = w.fetched[i].get();
            batch.snapshots[i] = {std::move(w.fetched[i]), lineage | 1u,
                                  reinterpret_cast<const std::uint8_t*>(snap->cells.data()),
                                  snap->lattice.cellRange};
        }
    });
    // 5. Each drawn request's instance and cell map (in double), in request order.
    batch.instances.resize(drawn);
    tbb::parallel_for(std::size_t(0), chunks, [&](std::size_t c) {
        std::uint32_t next = w.drawnBefore[c];
        for (std::size_t k = c * kChunk; k != chunkEnd(c); ++k) {
            if (w.places[k] == kHidden) continue;
            const SpriteSetup& sp = *requests[k].sprite;
            const std::uint32_t slot = w.needAt[w.places[k]];
            const SnapshotCellMap m = snapshotCellMap(sp.lattice, w.snapshots[slot]->lattice);
            batch.instances[next++] = {&sp,  slot, &models.at(std::size_t(sp.model))->palette(),
                                       m.u0, m.ui, m.uj,
                                       m.v0, m.vi, m.vj};
        }
    });
    const SnapshotCacheCounters after = cache.counters();
    batch.cacheUid = cache.uid();
    batch.cacheDrops = after.evictions + after.staleDropped;
    if (stats) {
        stats->sprites += drawn;
        stats->snapshotsUsed += distinct;
        addCacheWork(*stats, before, after);
        stats->ensureMs += msSince(t0);
    }
}

} // namespace voxtier
