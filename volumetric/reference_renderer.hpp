#pragma once
// The CPU reference tracer: the executable form of CONTRACT.md §3. It runs the shared sprite
// kernel (core/sprite_kernel.h) for every pixel of every sprite's screen rectangle, TBB-
// parallel over bands of rows, and writes with the shared depth/id rule. The Vulkan renderer must
// produce exactly this image.
#include "core/image.hpp"
#include "core/near_rate.hpp"
#include "core/sprite.hpp"
#include "core/voxel_model.hpp"
#include "core/work_progress.hpp"
#include "volumetric/near_stats.hpp"

#include <cstdint>
#include <memory>
#include <span>
#include <vector>

namespace voxtier {

/// How the reference traces: per pixel (the executable spec, default) or cell-rate where the
/// rate says so (core/near_rate.hpp); the image is the same either way.
struct ReferenceOptions {
    NearRate rate = NearRate::Fragment;
    std::uint64_t cellBudgetBytes = kDefaultCellBudgetBytes;
    /// Exact occlusion culling (core/occlusion.hpp): front to back, skipping the tiles and whole
    /// sprites the depth already drawn hides, before any of their cells is traced. Same image;
    /// off by default (CONTRACT.md §6, Occlusion: with the early depth test on, it costs more than
    /// it saves on every bench scene).
    bool occlusionCull = false;
    /// Skip the kernel where the pixel already holds what the depth/id rule keeps against the
    /// sprite (its one depth is known before any tracing), the sprites drawn front to back so
    /// that it rejects most of a crowd. Same image, fewer traces; off to count the voxel reads of
    /// the Vulkan counting shader, which traces every covered pixel, and under --no-cull.
    bool earlyDepthTest = true;
    /// Empty-space skipping (core/sprite_kernel.h): the traversal steps over the bricks the
    /// model frame's occupancy marks empty. Same image; off for the cell-by-cell traversal and its
    /// read counts, for comparisons.
    bool skipEmptyBricks = true;
    /// Where to count sprite rows (null: not counted): each run of sprites adds its rows (the
    /// screen rows of each sprite's rectangle) to total before it draws them, each band of rows
    /// what it finished. Cell-rate cells are traced inside the rows, so
    /// they are counted with them.
    WorkProgress* progress = nullptr;
};

/// Draws `sprites` (visible ones; culled entries are skipped) into `target`, which keeps what
/// it already holds (so tiers can draw into one image). Models are indexed by SpriteSetup::model.
void renderReference(const std::vector<std::shared_ptr<VoxelModel>>& models,
                     std::span<const SpriteSetup* const> sprites, Image& target,
                     ReferenceStats* stats = nullptr, const ReferenceOptions& options = {});

/// Convenience: every visible sprite of `all`.
void renderReference(const std::vector<std::shared_ptr<VoxelModel>>& models,
                     const std::vector<SpriteSetup>& all, Image& target,
                     ReferenceStats* stats = nullptr, const ReferenceOptions& options = {});

/// The kernel evaluated per lattice cell instead of per pixel: a (width x height) grid over
/// the sprite's cellRange with VT_KIND_* per cell and the palette index / face code of solid
/// cells, skipping the empty bricks of the grid's occupancy (built here). Tests compare this
/// with closed-form silhouettes.
struct CellImage {
    glm::ivec4 range{0}; ///< iMin, iMax, jMin, jMax
    std::vector<std::uint8_t> kind, index, face;
    int width() const { return range.y - range.x + 1; }
    int height() const { return range.w - range.z + 1; }
    std::size_t at(int i, int j) const {
        return std::size_t(j - range.z) * std::size_t(width()) + std::size_t(i - range.x);
    }
};
CellImage traceCells(const kernel::SpriteGpu& sprite, const VoxelGrid& grid);

} // namespace voxtier
