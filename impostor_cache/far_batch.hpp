#pragma once
// What a GPU far pass needs of the far tier's frame (CONTRACT.md §6, the far pass on Vulkan), as
// plain data: volumetric draws far sprites from this without knowing impostor_cache
// (ARCHITECTURE.md). impostor_cache fills it (prepareFarBatch: the frame's snapshots, looked up or
// baked, and each sprite's snapshot cell map); compose hands it to the near renderer, which draws
// the far sprites in the same frame, into the same targets, with the far blit's exact rule.
#include "core/sprite.hpp"
#include "core/voxel_model.hpp"

#include <cstdint>
#include <memory>
#include <vector>

namespace voxtier {

/// How the far pass is cut into workgroups: the same image every way (far_shared.h).
/// Coarse: a workgroup per 32 x 32-pixel tile that far rectangles touch, which passes the tile's
/// far sprites over its pixels one after another, nearest first, each pixel stopping at the
/// first sprite it refuses. Fine: the same over 8 x 8 tiles, 16 times as many workgroups, each
/// list read in batches through shared memory. Sprites: no tiles; a workgroup per far sprite
/// covers its rectangle, and each pixel it would draw and win takes the least such sprite's index
/// by an atomic minimum, then a pass over the image writes the winners (far_splat.comp): the work
/// is the rectangles' pixels once, however a crowd piles up over a few tiles. Auto: sprites. On
/// lavapipe the 100,000-tank hybrid's far pass takes 39-40 ms cut by sprite against 70-76 coarse
/// and all far 1,488-1,546 against 1,480-1,504 (fine: 2.5 times the coarse); on a GPU, where a
/// tile's walk runs one sprite after another while the rest of the device waits (the H200's
/// coarse pass: 7.7 ms for 9,700 far tanks), none of the three is measured against the others
/// yet (gpu_check.sh --profile renders all three).
enum class FarTiles : std::uint8_t { Auto, Coarse, Fine, Sprites };

/// Snapshot cell codes as a far pass reads them (impostor_cache/snapshot.hpp's snapshot_code,
/// which static_asserts that it says the same): 0 empty, 1 + f solid through entered face f,
/// 7 outline.
namespace far_cell {
inline constexpr std::uint32_t kEmpty = 0, kSolid0 = 1, kOutline = 7;
}

/// One snapshot: row-major cells over the inclusive lattice range cellRange (i0, i1, j0, j1), two
/// bytes per cell (palette index, code). `owner` keeps the cells alive; a device copy keyed by it
/// is dropped once nobody else holds the snapshot (the snapshot cache evicted it or replaced it
/// after an edit), which is how device residency follows the cache's budget.
struct FarSnapshotCells {
    std::shared_ptr<const void> owner;
    /// The same for every version of one (model, frame, view, sigma), 0 for none: a hint that
    /// lets a refreshed snapshot take over its predecessor's device copy and upload only the
    /// rows that changed (correct whatever it says: the rows are compared).
    std::uint64_t lineage = 0;
    const std::uint8_t* cells = nullptr;
    glm::ivec4 cellRange{0};
    int width() const { return cellRange.y - cellRange.x + 1; }
    int height() const { return cellRange.w - cellRange.z + 1; }
};

/// One far sprite: what it shows (its snapshot, its model's palette) and where each of its near
/// lattice cells reads the snapshot: cell (floor(u0 + ui i + uj j), floor(v0 + vi i + vj j)),
/// evaluated in double in that order (impostor_cache's SnapshotCellMap).
struct FarInstance {
    const SpriteSetup* sprite = nullptr; ///< visible
    std::uint32_t snapshot = 0;          ///< index into FarBatch::snapshots
    const Palette* palette = nullptr;
    double u0 = 0, ui = 0, uj = 0, v0 = 0, vi = 0, vj = 0;
};

/// The far sprites of one frame.
struct FarBatch {
    std::vector<FarSnapshotCells> snapshots; ///< distinct
    std::vector<FarInstance> instances;
    /// The snapshot cache the snapshots came from (SnapshotCache::uid) and the snapshots it had
    /// dropped by then (evicted or superseded): a device copy that only its residency still holds
    /// can appear only after either changes (FarResidency::update). 0: unknown (a batch put
    /// together by hand), as if both changed every frame.
    std::uint64_t cacheUid = 0, cacheDrops = 0;
    bool empty() const { return instances.empty(); }
};

} // namespace voxtier
