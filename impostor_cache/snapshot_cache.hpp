#pragma once
// The lazy snapshot cache of CONTRACT.md §4. A snapshot is keyed by (model uid, frame, model
// version, view direction (ViewId), sigma), baked the first time someone asks for it, shared by
// every entity of the model, baked once however many threads ask at the same time, and evicted
// least-recently-used over a byte budget. The Embree scene of a (model, frame, version) is kept
// apart from the per-view snapshots. Both are a VersionedLru (impostor_cache/versioned_lru.hpp).
//
// Invalidation (CONTRACT.md §4): an edit bumps the model version, so every key of the model goes
// stale at once and nothing stale is ever returned. Nothing is re-baked at edit time: the first
// request for a view at the new version finds that view's snapshot of the previous version, asks
// the model what changed since (VoxelModel::dirtySince) and re-traces only the cells whose rays
// can reach the dirty box (rebakeSnapshot); the new scene likewise rebuilds only the bricks the
// edit reaches (VoxelScene's derived constructor). The superseded snapshot and scene are dropped
// when their successor lands, so old versions never sit in the budget. Views nobody asks for stay
// stale until they are asked for, evicted, or the edit log no longer reaches back to them (then
// they are baked whole). A model shared by many entities is refreshed once per view.
#include "core/view_set.hpp"
#include "core/voxel_model.hpp"
#include "impostor_cache/snapshot.hpp"
#include "impostor_cache/snapshot_baker.hpp"
#include "impostor_cache/snapshot_store.hpp"
#include "impostor_cache/versioned_lru.hpp"
#include "impostor_cache/voxel_scene.hpp"

#include <cstddef>
#include <cstdint>
#include <functional>
#include <limits>
#include <memory>
#include <mutex>
#include <optional>
#include <span>
#include <unordered_map>

namespace voxtier {

struct SnapshotKey {
    std::uint64_t modelUid = 0;
    int frame = 0;
    std::uint64_t version = 0;
    ViewId view; ///< the snapshot's direction, shared by every view set that holds it
    double sigma = 1.0;
    bool operator==(const SnapshotKey&) const = default;
};

struct SnapshotCacheConfig {
    std::size_t budgetBytes = std::size_t(256) << 20; ///< snapshot bytes kept (LRU beyond)
    /// Embree scenes kept (LRU beyond): a byte budget, because a frame needs the scene of
    /// every (model, animation frame) it bakes a view of, and a scene rebuilt per bake costs
    /// several times the bake (docs/decisions/bake-cap-and-scene-budget.md).
    std::size_t sceneBudgetBytes = std::size_t(64) << 20;
    std::size_t maxScenes = std::numeric_limits<std::size_t>::max(); ///< and at most this many
    VoxelSceneOptions scene;
    BakeOptions bake;
    /// The on-disk cache (impostor_cache/snapshot_store.hpp), or null: a snapshot missing here is
    /// read from it before it is baked, and written to it after a full bake.
    std::shared_ptr<SnapshotStore> store;
};

struct SnapshotCacheCounters {
    std::uint64_t hits = 0;   ///< requests answered from the cache (incl. joining a bake in flight)
    std::uint64_t misses = 0; ///< requests that started a bake (or an on-disk cache read)
    std::uint64_t bakes = 0;  ///< snapshots baked
    std::uint64_t diskLoads = 0; ///< misses filled from the on-disk cache instead of a bake
    std::uint64_t evictions = 0; ///< snapshots dropped for the budget
    std::uint64_t bytes = 0;     ///< snapshot bytes held now
    std::uint64_t snapshots = 0; ///< snapshots held now
    std::uint64_t raysTraced = 0;
    std::uint64_t scenesBuilt = 0;
    std::uint64_t sceneBytes = 0; ///< bytes of the Embree scenes held now
    double bakeMs = 0.0, sceneMs = 0.0;
    /// Time in the on-disk store's reads and writes (size limit included), summed over threads:
    /// not part of what a bake costs (a render without the directory spends none of it).
    double storeMs = 0.0;
    // Invalidation: what edits cost.
    std::uint64_t refreshes = 0; ///< bakes that replaced a stale snapshot of the same view (a
                                 ///< subset of bakes; only views that are requested)
    std::uint64_t incrementalRefreshes = 0; ///< of those, only the cells the edit can reach
                                            ///< re-traced (none when the edit was elsewhere)
    std::uint64_t fullRefreshes = 0;  ///< of those, baked whole: the edit log no longer reached the
                                      ///< stale version, or the edit covers most of the snapshot
    std::uint64_t cellsRetraced = 0;  ///< rays traced by incremental refreshes (also in raysTraced)
    std::uint64_t cellsRefreshed = 0; ///< cells of the snapshots refreshed incrementally
    std::uint64_t staleDropped = 0;   ///< superseded snapshots dropped when their refresh landed
    std::uint64_t scenesUpdated = 0;  ///< scenes derived from the previous version's by rebuilding
                                      ///< only the bricks the edit reaches (subset of scenesBuilt)
    std::uint64_t bricksRebuilt = 0;  ///< bricks built by those derived scenes
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
    std::shared_ptr<const Snapshot> get(const VoxelModel& model, int frame, ViewId view,
                                        double sigma);
    /// One snapshot for getAll: get()'s arguments.
    struct Ask {
        const VoxelModel* model = nullptr;
        int frame = 0;
        ViewId view;
        double sigma = 0.0;
    };
    /// get() of each ask into out[i] (`out` as long as `asks`): the cached ones in one pass under
    /// the cache's lock, each made the most recent in ask order, then the rest baked (or loaded)
    /// in parallel as get() does. The same snapshots and counters as a get() per ask.
    void getAll(std::span<const Ask> asks, std::span<std::shared_ptr<const Snapshot>> out);
    /// View `index` of `set`.
    std::shared_ptr<const Snapshot> get(const VoxelModel& model, int frame, ViewSet set, int index,
                                        double sigma) {
        return get(model, frame, viewIdOf(set, index), sigma);
    }
    /// The cached snapshot or nullptr; never bakes, does not count or touch the LRU order.
    std::shared_ptr<const Snapshot> find(const SnapshotKey& key) const;
    /// Whether get() can have this snapshot without baking: cached here, or a file for it in
    /// the on-disk store (its existence only: get() still validates the file and bakes in place
    /// of a bad one). What a frame planner asks before counting a bake against its bound. Never
    /// bakes, counts or touches either LRU order; the disk answer is remembered per key and
    /// version until get() produces that key, so a frame of many entities costs few file
    /// lookups. An edited model with a cached older version is refreshed, not read from disk,
    /// whatever this says (a file of the edited voxels is rare: nobody pre-bakes an edit).
    bool availableWithoutBake(const VoxelModel& model, int frame, ViewId view, double sigma);
    /// Whether the snapshot is cached in this process's memory (the model's current version).
    /// Unlike availableWithoutBake, this depends only on what this process asked for, never on
    /// what other processes or earlier runs left in the directory: what a planner may prefer.
    bool inMemory(const VoxelModel& model, int frame, ViewId view, double sigma) const;
    /// Every snapshot whose inMemory() answer may differ from what it was after the first `since`
    /// changes of what memory holds (a snapshot baked, loaded, evicted or superseded), passed to
    /// `changed` as its key; returns the count of such changes so far (the next call's `since`),
    /// or nullopt when that is too long ago to tell (VersionedLru::changesSince). Edits are not
    /// changes: a model's new version answers for keys of that version. What lets a planner keep
    /// the answers of frames before.
    std::optional<std::uint64_t>
    inMemoryChangesSince(std::uint64_t since,
                         const std::function<void(const SnapshotKey&)>& changed) const;
    /// The count of those changes so far.
    std::uint64_t inMemoryChangeCount() const;
    /// The Embree scene of the model's current version of `frame` (built once, shared).
    std::shared_ptr<const VoxelScene> scene(const VoxelModel& model, int frame);

    SnapshotCacheCounters counters() const;
    const SnapshotCacheConfig& config() const { return config_; }
    /// Unique among the caches of this process (never 0): which cache a snapshot came from.
    std::uint64_t uid() const { return uid_; }
    /// Far sprites of sigma s draw from this cache's snapshots at sigma s x this (its bakes'
    /// snapshot scale, SelectorConfig::snapshotScale): the far frame asks for that sigma.
    int snapshotScale() const { return config_.bake.snapshotScale; }
    /// Changes the budget and evicts down to it.
    void setBudget(std::size_t bytes);

  private:
    std::uint64_t uid_;
    /// A snapshot key without its version: what stays the same across edits of the model.
    struct ViewKey {
        std::uint64_t modelUid;
        int frame;
        ViewId view;
        double sigma;
        bool operator==(const ViewKey&) const = default;
    };
    struct ViewKeyHash {
        std::size_t operator()(const ViewKey& k) const;
    };
    struct FrameKey {
        std::uint64_t modelUid;
        int frame;
        bool operator==(const FrameKey&) const = default;
    };
    struct FrameKeyHash {
        std::size_t operator()(const FrameKey& k) const;
    };

    /// The on-disk key of a snapshot of the model's current version of `frame`.
    SnapshotFileKey fileKey(const VoxelModel& model, int frame, ViewId view, double sigma);

    SnapshotCacheConfig config_;
    VersionedLru<ViewKey, Snapshot, ViewKeyHash> snapshots_;
    /// digestGrid of each (model, frame, version) the on-disk cache was asked about: computed
    /// once for all its views, since it reads every voxel of the frame.
    VersionedLru<FrameKey, Digest128, FrameKeyHash> digests_;
    VersionedLru<FrameKey, VoxelScene, FrameKeyHash> scenes_;
    /// availableWithoutBake's memory of the on-disk store: whether the key's file existed when
    /// last asked, for that model version. Cleared whole past kMaxDiskAnswers entries.
    struct DiskAnswer {
        std::uint64_t version;
        bool present;
    };
    static constexpr std::size_t kMaxDiskAnswers = std::size_t(1) << 16;
    std::unordered_map<ViewKey, DiskAnswer, ViewKeyHash> diskAnswers_;

    mutable std::mutex mutex_;       ///< for counters_ and diskAnswers_
    SnapshotCacheCounters counters_; ///< what baking and building cost; the LRU counts its own
};

} // namespace voxtier
