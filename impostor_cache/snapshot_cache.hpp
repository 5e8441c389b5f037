#pragma once
// The lazy snapshot cache of DESIGN.md §4. A snapshot is keyed by (model uid, frame, model
// version, view set, view, sigma), baked the first time someone asks for it, shared by every
// entity of the model, baked once however many threads ask at the same time, and evicted
// least-recently-used over a byte budget. The Embree scene of a (model, frame, version) is kept
// apart from the per-view snapshots, so a later incremental re-bake after an edit can reuse the
// snapshot of the previous version and re-trace only the dirty cells.
#include "core/voxel_model.hpp"
#include "impostor_cache/snapshot.hpp"
#include "impostor_cache/snapshot_baker.hpp"
#include "impostor_cache/view_set.hpp"
#include "impostor_cache/voxel_scene.hpp"

#include <cstddef>
#include <cstdint>
#include <list>
#include <memory>
#include <mutex>
#include <unordered_map>

namespace voxtier {

struct SnapshotKey {
    std::uint64_t modelUid = 0;
    int frame = 0;
    std::uint64_t version = 0;
    ViewSet set = ViewSet::Cube26;
    int view = 0;
    double sigma = 1.0;
    bool operator==(const SnapshotKey&) const = default;
};

struct SnapshotCacheConfig {
    std::size_t budgetBytes = std::size_t(256) << 20; ///< snapshot bytes kept (LRU beyond)
    std::size_t maxScenes = 8;                        ///< Embree scenes kept (LRU beyond)
    VoxelSceneOptions scene;
    BakeOptions bake;
};

struct SnapshotCacheCounters {
    std::uint64_t hits = 0;   ///< requests answered from the cache (incl. joining a bake in flight)
    std::uint64_t misses = 0; ///< requests that started a bake
    std::uint64_t bakes = 0;  ///< snapshots baked
    std::uint64_t evictions = 0; ///< snapshots dropped for the budget
    std::uint64_t bytes = 0;     ///< snapshot bytes held now
    std::uint64_t snapshots = 0; ///< snapshots held now
    std::uint64_t raysTraced = 0;
    std::uint64_t scenesBuilt = 0;
    std::uint64_t sceneBytes = 0; ///< bytes of the Embree scenes held now
    double bakeMs = 0.0, sceneMs = 0.0;
};

class SnapshotCache {
  public:
    explicit SnapshotCache(SnapshotCacheConfig config = {});
    ~SnapshotCache();
    SnapshotCache(const SnapshotCache&) = delete;
    SnapshotCache& operator=(const SnapshotCache&) = delete;

    /// The snapshot of `view` for the model's current version of `frame`, baked now if
    /// missing. Thread-safe; concurrent requests for one key bake once (the callers that wait
    /// help with that bake's parallel work). The returned pointer stays valid after eviction.
    std::shared_ptr<const Snapshot> get(const VoxelModel& model, int frame, ViewSet set, int view,
                                        double sigma);
    /// The cached snapshot or nullptr; never bakes, does not count or touch the LRU order.
    std::shared_ptr<const Snapshot> find(const SnapshotKey& key) const;
    /// The Embree scene of the model's current version of `frame` (built once, shared).
    std::shared_ptr<const VoxelScene> scene(const VoxelModel& model, int frame);

    SnapshotCacheCounters counters() const;
    const SnapshotCacheConfig& config() const { return config_; }
    /// Changes the budget and evicts down to it.
    void setBudget(std::size_t bytes);

    struct KeyHash {
        std::size_t operator()(const SnapshotKey& k) const;
    };

  private:
    struct Entry;
    struct SceneEntry;
    struct SceneKey {
        std::uint64_t modelUid;
        int frame;
        std::uint64_t version;
        bool operator==(const SceneKey&) const = default;
    };
    struct SceneKeyHash {
        std::size_t operator()(const SceneKey& k) const;
    };
    void evictLocked(); // mutex_ held

    SnapshotCacheConfig config_;
    mutable std::mutex mutex_;
    std::unordered_map<SnapshotKey, std::shared_ptr<Entry>, KeyHash> entries_;
    std::list<SnapshotKey> lru_; ///< ready snapshots, most recent first
    std::unordered_map<SceneKey, std::shared_ptr<SceneEntry>, SceneKeyHash> scenes_;
    std::list<SceneKey> sceneLru_;
    SnapshotCacheCounters counters_;
};

} // namespace voxtier
