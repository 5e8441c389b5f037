#include "impostor_cache/snapshot_cache.hpp"

#include "core/process_uid.hpp"
#include "core/stopwatch.hpp"

#include <tbb/parallel_for.h>

#include <chrono>
#include <functional>
#include <optional>
#include <stdexcept>
#include <utility>

namespace voxtier {

namespace {
std::size_t mix(std::size_t h, std::size_t v) {
    return h ^ (v + 0x9e3779b97f4a7c15ull + (h << 6) + (h >> 2));
}
} // namespace

std::size_t SnapshotCache::ViewKeyHash::operator()(const ViewKey& k) const {
    std::size_t h = std::hash<std::uint64_t>{}(k.modelUid);
    h = mix(h, std::hash<int>{}(k.frame));
    for (int c = 0; c < 3; ++c) h = mix(h, std::hash<int>{}(k.view.lattice[c]));
    return mix(h, std::hash<double>{}(k.sigma));
}

std::size_t SnapshotCache::FrameKeyHash::operator()(const FrameKey& k) const {
    return mix(std::hash<std::uint64_t>{}(k.modelUid), std::hash<int>{}(k.frame));
}

SnapshotCache::SnapshotCache(SnapshotCacheConfig config)
    : uid_(newProcessUid()), config_(config), snapshots_(LruBudget{config.budgetBytes}),
      digests_(LruBudget{.entries = 256}),
      scenes_(LruBudget{.bytes = config.sceneBudgetBytes, .entries = config.maxScenes}) {}
SnapshotCache::~SnapshotCache() = default;

std::shared_ptr<const VoxelScene> SnapshotCache::scene(const VoxelModel& model, int frame) {
    using Older = decltype(scenes_)::Older;
    return scenes_.get({model.uid(), frame}, model.version(), [&](const std::optional<Older>& old) {
        // After an edit: derive the scene from the previous version's, rebuilding only the
        // bricks the edit reaches; when nothing in this frame changed it is that very scene.
        const std::optional<Box3i> dirty =
            old ? model.dirtySince(old->version, frame) : std::nullopt;
        if (dirty && dirty->empty()) return old->value;
        const std::shared_ptr<const VoxelScene> built =
            dirty ? std::make_shared<const VoxelScene>(*old->value, model.frame(frame), *dirty)
                  : std::make_shared<const VoxelScene>(model.frame(frame), config_.scene);
        std::lock_guard lock(mutex_);
        ++counters_.scenesBuilt;
        counters_.sceneMs += built->buildMs();
        if (dirty) {
            ++counters_.scenesUpdated;
            counters_.bricksRebuilt += built->buildStats().bricksBuilt;
        }
        return built;
    });
}

std::shared_ptr<const Snapshot> SnapshotCache::get(const VoxelModel& model, int frame, ViewId view,
                                                   double sigma) {
    using Older = decltype(snapshots_)::Older;
    const ViewKey key{model.uid(), frame, view, sigma};
    return snapshots_.get(key, model.version(), [&](const std::optional<Older>& stale) {
        {
            // Whatever happens below (a load, a bake, a file write that fails), the next
            // availableWithoutBake of this key looks at the directory again.
            std::lock_guard lock(mutex_);
            diskAnswers_.erase(key);
        }
        // A stale snapshot of this view (an older version of the model) is brought up to date
        // where the edits since reach, if the model's log still knows what they were; otherwise
        // the per-(model, frame, version) scene (shared by all views) bakes this view whole.
        const std::optional<Box3i> dirty =
            stale ? model.dirtySince(stale->version, frame) : std::nullopt;
        BakeStats stats;
        std::shared_ptr<const Snapshot> snap;
        if (dirty && dirty->empty()) {
            snap = stale->value; // edits in other frames of the model: the same bytes
            stats.incremental = 1;
            stats.cells = snap->cells.size();
        } else if (dirty) {
            const std::shared_ptr<const VoxelScene> sc = scene(model, frame);
            snap = std::make_shared<const Snapshot>(
                rebakeSnapshot(*sc, *stale->value, *dirty, config_.bake, &stats));
        } else {
            // A whole snapshot is needed: the on-disk cache has it if anyone baked these voxels.
            std::optional<SnapshotFileKey> fileKey;
            if (config_.store) {
                const auto t0 = std::chrono::steady_clock::now();
                fileKey = this->fileKey(model, frame, view, sigma);
                std::optional<Snapshot> loaded = config_.store->load(*fileKey);
                std::lock_guard lock(mutex_);
                counters_.storeMs += msSince(t0);
                if (loaded) {
                    ++counters_.diskLoads;
                    return std::make_shared<const Snapshot>(std::move(*loaded));
                }
            }
            const std::shared_ptr<const VoxelScene> sc = scene(model, frame);
            snap = std::make_shared<const Snapshot>(
                bakeSnapshot(*sc, view, sigma, config_.bake, &stats));
            if (fileKey) {
                const auto t0 = std::chrono::steady_clock::now();
                config_.store->save(*fileKey, *snap);
                std::lock_guard lock(mutex_);
                counters_.storeMs += msSince(t0);
            }
        }
        std::lock_guard lock(mutex_);
        ++counters_.bakes;
        counters_.raysTraced += stats.rays;
        counters_.bakeMs += stats.ms;
        if (stale) {
            ++counters_.refreshes;
            if (stats.incremental) {
                ++counters_.incrementalRefreshes;
                counters_.cellsRetraced += stats.rays;
                counters_.cellsRefreshed += stats.cells;
            } else {
                ++counters_.fullRefreshes;
            }
        }
        return snap;
    });
}

void SnapshotCache::getAll(std::span<const Ask> asks,
                           std::span<std::shared_ptr<const Snapshot>> out) {
    if (out.size() != asks.size())
        throw std::invalid_argument("SnapshotCache::getAll: one result per ask");
    snapshots_.takeReady(
        asks.size(),
        [&](std::size_t i) {
            const Ask& a = asks[i];
            return std::pair{ViewKey{a.model->uid(), a.frame, a.view, a.sigma}, a.model->version()};
        },
        out.data());
    tbb::parallel_for(std::size_t(0), asks.size(), [&](std::size_t i) {
        if (!out[i]) out[i] = get(*asks[i].model, asks[i].frame, asks[i].view, asks[i].sigma);
    });
}

SnapshotFileKey SnapshotCache::fileKey(const VoxelModel& model, int frame, ViewId view,
                                       double sigma) {
    const std::shared_ptr<const Digest128> grid =
        digests_.get({model.uid(), frame}, model.version(), [&](const auto&) {
            return std::make_shared<const Digest128>(digestGrid(model.frame(frame)));
        });
    return {*grid, model.frame(frame).dims(), view,
            sigma, config_.bake.withDepth,    config_.bake.snapshotScale};
}

std::shared_ptr<const Snapshot> SnapshotCache::find(const SnapshotKey& key) const {
    return snapshots_.find({key.modelUid, key.frame, key.view, key.sigma}, key.version);
}

bool SnapshotCache::availableWithoutBake(const VoxelModel& model, int frame, ViewId view,
                                         double sigma) {
    const ViewKey key{model.uid(), frame, view, sigma};
    if (snapshots_.find(key, model.version())) return true;
    if (!config_.store) return false;
    {
        std::lock_guard lock(mutex_);
        const auto known = diskAnswers_.find(key);
        if (known != diskAnswers_.end() && known->second.version == model.version())
            return known->second.present;
    }
    const bool present = config_.store->contains(fileKey(model, frame, view, sigma));
    std::lock_guard lock(mutex_);
    if (diskAnswers_.size() >= kMaxDiskAnswers) diskAnswers_.clear();
    diskAnswers_[key] = {model.version(), present};
    return present;
}

bool SnapshotCache::inMemory(const VoxelModel& model, int frame, ViewId view, double sigma) const {
    return snapshots_.contains({model.uid(), frame, view, sigma}, model.version());
}

std::optional<std::uint64_t>
SnapshotCache::inMemoryChangesSince(std::uint64_t since,
                                    const std::function<void(const SnapshotKey&)>& changed) const {
    return snapshots_.changesSince(since, [&](const ViewKey& k, std::uint64_t version) {
        changed(SnapshotKey{k.modelUid, k.frame, version, k.view, k.sigma});
    });
}

std::uint64_t SnapshotCache::inMemoryChangeCount() const {
    return snapshots_.changeCount();
}

SnapshotCacheCounters SnapshotCache::counters() const {
    SnapshotCacheCounters c;
    {
        std::lock_guard lock(mutex_);
        c = counters_;
    }
    const LruStats snapshots = snapshots_.stats();
    c.hits = snapshots.hits;
    c.misses = snapshots.misses;
    c.evictions = snapshots.evictions;
    c.staleDropped = snapshots.superseded;
    c.bytes = snapshots.bytes;
    c.snapshots = snapshots.entries;
    c.sceneBytes = scenes_.stats().bytes;
    return c;
}

void SnapshotCache::setBudget(std::size_t bytes) {
    {
        std::lock_guard lock(mutex_);
        config_.budgetBytes = bytes;
    }
    snapshots_.setBudget(LruBudget{bytes});
}

} // namespace voxtier
