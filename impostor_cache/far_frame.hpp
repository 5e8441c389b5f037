#pragma once
// The far half of a frame (CONTRACT.md §6): choose each far sprite's view, make sure the
// snapshots it needs exist (lazy, parallel over distinct snapshots), then blit them.
#include "core/image.hpp"
#include "core/sprite.hpp"
#include "core/voxel_model.hpp"
#include "impostor_cache/far_batch.hpp"
#include "impostor_cache/far_blit.hpp"
#include "impostor_cache/snapshot_cache.hpp"

#include <memory>
#include <optional>
#include <span>
#include <vector>

namespace voxtier {

/// One far sprite to draw; `view` overrides the nearest-view choice (a selector applying angular
/// hysteresis or an error budget, with a view of any set or ladder level), nullopt =
/// chooseFarView in the frame's set.
struct FarRequest {
    const SpriteSetup* sprite = nullptr;
    std::optional<ViewId> view;
};

/// Draws `requests` (culled sprites are skipped) through `cache` into `target`. Models are
/// indexed by SpriteSetup::model; each sprite's snapshot has the sprite's sigma times the
/// cache's snapshotScale().
void drawFarSprites(const std::vector<std::shared_ptr<VoxelModel>>& models,
                    std::span<const FarRequest> requests, SnapshotCache& cache, ViewSet set,
                    Image& target, FarFrameStats* stats = nullptr, const FarBlitOptions& blit = {});

/// drawFarSprites in its two halves, for a frame without occlusion culling (which interleaves
/// them, a run at a time): the far sprites with their snapshots looked up or baked (in parallel
/// over distinct snapshots) and held, not yet drawn. A frame whose near tier is on the device
/// makes them while the device draws, and blits them once the near image, whose depth and ids
/// the blit composes on, is read back (compose's FrameRenderer).
struct FarDraws {
    std::vector<FarSprite> sprites;                    ///< visible ones, drawFarSprites' order
    std::vector<std::shared_ptr<const Snapshot>> held; ///< the distinct snapshots they show
    /// The snapshot cache's counters around the lookups (what they baked) and their time.
    SnapshotCacheCounters cacheBefore, cacheAfter;
    double ensureMs = 0.0;
};
/// The first half: what drawFarSprites looks up and bakes without culling, the same snapshots.
FarDraws fetchFarSnapshots(const std::vector<std::shared_ptr<VoxelModel>>& models,
                           std::span<const FarRequest> requests, SnapshotCache& cache, ViewSet set);
/// The second: blits `draws` into `target` (the same image as drawFarSprites of the same
/// requests without culling), adding the lookups' and the blit's figures to `stats`.
/// `blit.occlusionCull` must be off.
void blitFarDraws(const FarDraws& draws, Image& target, FarFrameStats* stats = nullptr,
                  const FarBlitOptions& blit = {});

/// The far half of a frame for a GPU far pass (impostor_cache/far_batch.hpp): the same snapshots as
/// drawFarSprites (looked up or baked, in parallel over distinct snapshots) and, per visible
/// sprite, its snapshot cell map; nothing drawn (stats->blit stays 0). No occlusion culling.
/// The snapshots in the order the requests first show them; the instances in request order.
FarBatch prepareFarBatch(const std::vector<std::shared_ptr<VoxelModel>>& models,
                         std::span<const FarRequest> requests, SnapshotCache& cache, ViewSet set,
                         FarFrameStats* stats = nullptr);

/// What prepareFarBatch needs besides its result, kept from frame to frame by a renderer: arrays
/// of the requests' size and a table of their distinct snapshots.
class FarBatchScratch {
  public:
    FarBatchScratch();
    ~FarBatchScratch();
    FarBatchScratch(FarBatchScratch&&) noexcept;
    FarBatchScratch& operator=(FarBatchScratch&&) noexcept;
    struct Impl;

  private:
    friend void prepareFarBatch(const std::vector<std::shared_ptr<VoxelModel>>&,
                                std::span<const FarRequest>, SnapshotCache&, ViewSet, FarBatch&,
                                FarBatchScratch&, FarFrameStats*);
    std::unique_ptr<Impl> impl_;
};

/// prepareFarBatch into `batch` (every field replaced; its arrays' storage reused), with
/// `scratch`'s arrays: the same batch, and nothing of O(requests) allocated once they have grown.
/// Every step runs on every core, the distinct snapshots found through a shared table: at 67,000
/// far tanks one core hashing each request into a map cost ~10 ms of a frame.
void prepareFarBatch(const std::vector<std::shared_ptr<VoxelModel>>& models,
                     std::span<const FarRequest> requests, SnapshotCache& cache, ViewSet set,
                     FarBatch& batch, FarBatchScratch& scratch, FarFrameStats* stats = nullptr);

} // namespace voxtier
