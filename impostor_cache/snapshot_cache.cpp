#include "impostor_cache/snapshot_cache.hpp"

#include <tbb/collaborative_call_once.h>

#include <algorithm>
#include <chrono>
#include <functional>
#include <optional>

namespace voxtier {

struct SnapshotCache::Entry {
    // collaborative_call_once: one thread bakes, the others that ask meanwhile join its
    // parallel work inside an isolated region (a plain mutex or future would leave them idle,
    // and a TBB worker blocked on a future could be the one the bake is waiting for).
    tbb::collaborative_once_flag once;
    std::shared_ptr<const Snapshot> snapshot; // set once, under `once`
    std::size_t bytes = 0;
    bool listed = false;                     // in lru_ (ready and not evicted); mutex_
    std::list<SnapshotKey>::iterator lruPos; // valid when listed; mutex_
};

struct SnapshotCache::SceneEntry {
    tbb::collaborative_once_flag once;
    std::shared_ptr<const VoxelScene> scene;
    bool listed = false;
    std::list<SceneKey>::iterator lruPos;
};

namespace {
std::size_t mix(std::size_t h, std::size_t v) {
    return h ^ (v + 0x9e3779b97f4a7c15ull + (h << 6) + (h >> 2));
}
} // namespace

std::size_t SnapshotCache::KeyHash::operator()(const SnapshotKey& k) const {
    std::size_t h = std::hash<std::uint64_t>{}(k.modelUid);
    h = mix(h, std::hash<int>{}(k.frame));
    h = mix(h, std::hash<std::uint64_t>{}(k.version));
    h = mix(h, std::hash<int>{}(int(k.set)));
    h = mix(h, std::hash<int>{}(k.view));
    return mix(h, std::hash<double>{}(k.sigma));
}

std::size_t SnapshotCache::SceneKeyHash::operator()(const SceneKey& k) const {
    return mix(mix(std::hash<std::uint64_t>{}(k.modelUid), std::hash<int>{}(k.frame)),
               std::hash<std::uint64_t>{}(k.version));
}

SnapshotCache::SnapshotCache(SnapshotCacheConfig config) : config_(config) {}
SnapshotCache::~SnapshotCache() = default;

namespace {
SnapshotKey viewKeyOf(SnapshotKey k) {
    k.version = 0;
    return k;
}
} // namespace

std::shared_ptr<const Snapshot> SnapshotCache::staleLocked(const SnapshotKey& key,
                                                           std::uint64_t* version) const {
    const auto l = latest_.find(viewKeyOf(key));
    if (l == latest_.end() || l->second >= key.version) return nullptr;
    SnapshotKey old = key;
    old.version = l->second;
    const auto it = entries_.find(old);
    if (it == entries_.end() || !it->second->listed) return nullptr;
    *version = old.version;
    return it->second->snapshot;
}

std::shared_ptr<const VoxelScene> SnapshotCache::staleSceneLocked(const SceneKey& key,
                                                                  std::uint64_t* version) const {
    const auto l = latestScene_.find({key.modelUid, key.frame, 0});
    if (l == latestScene_.end() || l->second >= key.version) return nullptr;
    const auto it = scenes_.find({key.modelUid, key.frame, l->second});
    if (it == scenes_.end() || !it->second->listed) return nullptr;
    *version = l->second;
    return it->second->scene;
}

void SnapshotCache::dropSceneLocked(const SceneKey key) {
    const auto it = scenes_.find(key);
    if (it == scenes_.end()) return;
    SceneEntry& e = *it->second;
    if (e.listed) {
        sceneLru_.erase(e.lruPos);
        e.listed = false;
        counters_.sceneBytes -= e.scene ? e.scene->bytes() : 0;
    }
    const auto l = latestScene_.find({key.modelUid, key.frame, 0});
    if (l != latestScene_.end() && l->second == key.version) latestScene_.erase(l);
    scenes_.erase(it); // bakes in flight hold their own reference
}

std::shared_ptr<const VoxelScene> SnapshotCache::scene(const VoxelModel& model, int frame) {
    const SceneKey key{model.uid(), frame, model.version()};
    std::shared_ptr<SceneEntry> e;
    {
        std::lock_guard lock(mutex_);
        auto& slot = scenes_[key];
        if (!slot) slot = std::make_shared<SceneEntry>();
        e = slot;
    }
    tbb::collaborative_call_once(e->once, [&] {
        // After an edit: derive the scene from the previous version's, rebuilding only the
        // bricks the edit reaches; when nothing in this frame changed it is that very scene.
        std::uint64_t oldVersion = 0;
        std::shared_ptr<const VoxelScene> previous;
        {
            std::lock_guard lock(mutex_);
            previous = staleSceneLocked(key, &oldVersion);
        }
        const std::optional<Box3i> dirty =
            previous ? model.dirtySince(oldVersion, frame) : std::nullopt;
        bool built = true;
        if (dirty && dirty->empty()) {
            e->scene = previous;
            built = false;
        } else if (dirty) {
            e->scene = std::make_shared<const VoxelScene>(*previous, model.frame(frame), *dirty);
        } else {
            e->scene = std::make_shared<const VoxelScene>(model.frame(frame), config_.scene);
        }
        std::lock_guard lock(mutex_);
        if (built) {
            ++counters_.scenesBuilt;
            counters_.sceneMs += e->scene->buildMs();
        }
        if (built && dirty) {
            ++counters_.scenesUpdated;
            counters_.bricksRebuilt += e->scene->buildStats().bricksBuilt;
        }
        counters_.sceneBytes += e->scene->bytes();
        // The superseded version is never asked for again (keys carry the current version).
        if (previous) dropSceneLocked({key.modelUid, key.frame, oldVersion});
        auto& newest = latestScene_[{key.modelUid, key.frame, 0}];
        newest = std::max(newest, key.version);
        // Listed here, under the same lock as the byte count, so the count always matches.
        e->listed = true;
        sceneLru_.push_front(key);
        e->lruPos = sceneLru_.begin();
    });
    std::lock_guard lock(mutex_);
    // LRU over scenes: bakers in flight hold their own reference, so dropping one here never
    // pulls it from under a bake.
    auto it = scenes_.find(key);
    if (it != scenes_.end() && it->second == e && e->listed) {
        sceneLru_.splice(sceneLru_.begin(), sceneLru_, e->lruPos);
        while (sceneLru_.size() > config_.maxScenes) dropSceneLocked(sceneLru_.back());
    }
    return e->scene;
}

std::shared_ptr<const Snapshot> SnapshotCache::get(const VoxelModel& model, int frame, ViewSet set,
                                                   int view, double sigma) {
    const SnapshotKey key{model.uid(), frame, model.version(), set, view, sigma};
    std::shared_ptr<Entry> e;
    {
        std::lock_guard lock(mutex_);
        auto it = entries_.find(key);
        if (it != entries_.end()) {
            e = it->second;
            ++counters_.hits;
            if (e->listed) lru_.splice(lru_.begin(), lru_, e->lruPos); // most recent first
            if (e->snapshot) return e->snapshot; // ready; written under mutex_
        } else {
            e = std::make_shared<Entry>();
            entries_.emplace(key, e);
            ++counters_.misses;
        }
    }
    // A bake in flight (or a failed one, which is retried): join it or run it. Completion of
    // the once orders the write of e->snapshot before the read below.
    tbb::collaborative_call_once(e->once, [&] {
        // A stale snapshot of this view (an older version of the model) is brought up to date
        // where the edits since reach, if the model's log still knows what they were; otherwise
        // the per-(model, frame, version) scene (shared by all views) bakes this view whole.
        std::uint64_t oldVersion = 0;
        std::shared_ptr<const Snapshot> stale;
        {
            std::lock_guard lock(mutex_);
            stale = staleLocked(key, &oldVersion);
        }
        const std::optional<Box3i> dirty =
            stale ? model.dirtySince(oldVersion, frame) : std::nullopt;
        BakeStats stats;
        std::shared_ptr<const Snapshot> snap;
        if (dirty && dirty->empty()) {
            snap = stale; // edits in other frames of the model: the same bytes
            stats.incremental = 1;
            stats.cells = snap->cells.size();
        } else if (dirty) {
            const std::shared_ptr<const VoxelScene> sc = scene(model, frame);
            snap = std::make_shared<const Snapshot>(
                rebakeSnapshot(*sc, *stale, *dirty, config_.bake, &stats));
        } else {
            const std::shared_ptr<const VoxelScene> sc = scene(model, frame);
            snap = std::make_shared<const Snapshot>(
                bakeSnapshot(*sc, set, view, sigma, config_.bake, &stats));
        }
        std::lock_guard lock(mutex_);
        e->snapshot = snap;
        e->bytes = snap->bytes();
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
            SnapshotKey old = key;
            old.version = oldVersion;
            if (entries_.count(old)) {
                dropLocked(old);
                ++counters_.staleDropped;
            }
        }
        // Still wanted (not dropped by a concurrent eviction of a never-listed entry): list it.
        auto it = entries_.find(key);
        if (it != entries_.end() && it->second == e) {
            lru_.push_front(key);
            e->lruPos = lru_.begin();
            e->listed = true;
            counters_.bytes += e->bytes;
            ++counters_.snapshots;
            auto& newest = latest_[viewKeyOf(key)];
            newest = std::max(newest, key.version);
            evictLocked();
        }
    });
    return e->snapshot;
}

void SnapshotCache::dropLocked(const SnapshotKey key) {
    const auto it = entries_.find(key);
    if (it == entries_.end()) return;
    Entry& e = *it->second;
    if (e.listed) {
        lru_.erase(e.lruPos);
        e.listed = false;
        counters_.bytes -= e.bytes;
        --counters_.snapshots;
    }
    const auto l = latest_.find(viewKeyOf(key));
    if (l != latest_.end() && l->second == key.version) latest_.erase(l);
    entries_.erase(it); // holders of the snapshot keep it alive
}

void SnapshotCache::evictLocked() {
    while (counters_.bytes > config_.budgetBytes && !lru_.empty()) {
        dropLocked(lru_.back());
        ++counters_.evictions;
    }
}

std::shared_ptr<const Snapshot> SnapshotCache::find(const SnapshotKey& key) const {
    std::lock_guard lock(mutex_);
    auto it = entries_.find(key);
    return it != entries_.end() && it->second->listed ? it->second->snapshot : nullptr;
}

SnapshotCacheCounters SnapshotCache::counters() const {
    std::lock_guard lock(mutex_);
    return counters_;
}

void SnapshotCache::setBudget(std::size_t bytes) {
    std::lock_guard lock(mutex_);
    config_.budgetBytes = bytes;
    evictLocked();
}

} // namespace voxtier
