#include "impostor_cache/snapshot_cache.hpp"

#include <tbb/collaborative_call_once.h>

#include <chrono>
#include <functional>

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
        e->scene = std::make_shared<const VoxelScene>(model.frame(frame), config_.scene);
        std::lock_guard lock(mutex_);
        ++counters_.scenesBuilt;
        counters_.sceneMs += e->scene->buildMs();
        counters_.sceneBytes += e->scene->bytes();
    });
    std::lock_guard lock(mutex_);
    // LRU over scenes: bakers in flight hold their own reference, so dropping one here never
    // pulls it from under a bake. A newer version of the same model frame simply outlives the
    // older one in this order.
    auto it = scenes_.find(key);
    if (it != scenes_.end() && it->second == e) {
        if (e->listed) sceneLru_.erase(e->lruPos);
        sceneLru_.push_front(key);
        e->lruPos = sceneLru_.begin();
        e->listed = true;
        while (sceneLru_.size() > config_.maxScenes) {
            const SceneKey old = sceneLru_.back();
            sceneLru_.pop_back();
            auto o = scenes_.find(old);
            if (o != scenes_.end()) {
                counters_.sceneBytes -= o->second->scene ? o->second->scene->bytes() : 0;
                scenes_.erase(o);
            }
        }
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
        // The per-(model, frame, version) scene first (shared by all views), then this view.
        // An incremental path would slot in here: find the same key with an older version,
        // ask model.dirtySince(old) and re-trace only the cells whose rays cross the box.
        const std::shared_ptr<const VoxelScene> sc = scene(model, frame);
        BakeStats stats;
        auto snap = std::make_shared<const Snapshot>(
            bakeSnapshot(*sc, set, view, sigma, config_.bake, &stats));
        std::lock_guard lock(mutex_);
        e->snapshot = snap;
        e->bytes = snap->bytes();
        ++counters_.bakes;
        counters_.raysTraced += stats.rays;
        counters_.bakeMs += stats.ms;
        // Still wanted (not dropped by a concurrent eviction of a never-listed entry): list it.
        auto it = entries_.find(key);
        if (it != entries_.end() && it->second == e) {
            lru_.push_front(key);
            e->lruPos = lru_.begin();
            e->listed = true;
            counters_.bytes += e->bytes;
            ++counters_.snapshots;
            evictLocked();
        }
    });
    return e->snapshot;
}

void SnapshotCache::evictLocked() {
    while (counters_.bytes > config_.budgetBytes && !lru_.empty()) {
        const SnapshotKey old = lru_.back();
        lru_.pop_back();
        auto it = entries_.find(old);
        if (it == entries_.end()) continue;
        it->second->listed = false;
        counters_.bytes -= it->second->bytes;
        --counters_.snapshots;
        ++counters_.evictions;
        entries_.erase(it); // holders of the snapshot keep it alive
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
