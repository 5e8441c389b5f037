#pragma once
// What each far backend reports of the frames it draws: the cache's work for the far sprites
// (FarFrameStats, whichever backend draws them), the CPU blit (FarBlitStats) and the Vulkan far
// pass (FarPassStats). compose's FrameStats holds them as the backends wrote them; the frame's
// output columns read them through compose/frame_figures.hpp.
#include <cstdint>

namespace voxtier {

/// What the CPU blit did in one frame.
struct FarBlitStats {
    std::uint64_t sprites = 0; ///< sprites drawn
    std::uint64_t pixelsTested =
        0; ///< pixels evaluated (of each row, the columns that can hold a cell)
    std::uint64_t pixelsWritten = 0; ///< pixels a solid or outline snapshot cell won
    /// (sprite, 16-row tile row) parts not drawn because occlusion tiles hid them
    std::uint64_t partsCulled = 0;
    double milliseconds = 0.0;
};

/// The far tier's frame through the snapshot cache: the lookups and the bakes they started, and,
/// drawn by the CPU blit, the blit's own figures.
struct FarFrameStats {
    std::uint64_t sprites = 0;       ///< visible sprites drawn through the cache
    std::uint64_t culled = 0;        ///< visible sprites occlusion culling dropped whole
    std::uint64_t snapshotsUsed = 0; ///< distinct snapshots this frame
    std::uint64_t bakes = 0;         ///< of those, baked during this frame
    std::uint64_t scenesBuilt = 0;   ///< Embree scenes those bakes built first
    /// Of the bakes, stale snapshots brought up to date after an edit; of those, the ones
    /// re-traced only where the edit reaches, and the rays they traced (SnapshotCacheCounters).
    std::uint64_t refreshes = 0, incrementalRefreshes = 0, cellsRetraced = 0;
    std::uint64_t raysTraced = 0; ///< by those bakes (SnapshotCacheCounters::raysTraced)
    double ensureMs = 0.0;        ///< lookups + bakes
    FarBlitStats blit;
};

/// What the far pass did in one frame.
struct FarPassStats {
    /// Far sprites drawn, image tiles walked, snapshots (and their bytes) uploaded this frame.
    std::uint64_t sprites = 0, tiles = 0, snapshotsUploaded = 0, bytesUploaded = 0;
    /// Of the sprites, those whose record the frame's slot already held (FarPass::record with a
    /// history); whether the draw order and tile lists were last frame's.
    std::uint64_t recordsKept = 0;
    bool orderKept = false;
    /// Cut by sprite: the splat's workgroups, one per chunk of each drawn rectangle
    /// (FAR_SPLAT_CHUNK pixels; 0 when cut by tiles).
    std::uint64_t splatGroups = 0;
    /// Host ms writing this frame's snapshot uploads into the staging ring and recording their
    /// copies (FarResidency::recordUploads); their device time is the far pass's "far_snapshots".
    double snapshotUploadMs = 0.0;
};

} // namespace voxtier
