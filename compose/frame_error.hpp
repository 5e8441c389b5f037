#pragma once
// The error of an approximate frame (far, hybrid) against the all-near render of the same frame
// (DESIGN.md §8), per entity and summarised over the entities the far tier drew: footprint
// mismatch, silhouette displacement in screen pixels and in virtual pixels, RMSE / PSNR.
#include "compose/error_metrics.hpp"
#include "compose/frame.hpp"

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

namespace voxtier {

/// Mean and worst over a set of entities.
struct EntityErrorSummary {
    std::size_t entities = 0;
    double meanMismatch = 0.0, worstMismatch = 0.0; ///< footprint mismatch fraction (0..1)
    double meanCoverageMismatch = 0.0; ///< the same counting only pixels owned in one image
    std::uint32_t worstMismatchEntity = 0;
    /// Silhouette displacement (EntityError::silhouetteDisplacementPx), screen pixels; entities
    /// present in only one image are counted in `missing`, not here.
    double meanDisplacementPx = 0.0, worstDisplacementPx = 0.0;
    /// The same in virtual pixels: divided by the on-screen size of one lattice cell of the
    /// entity, taken as at least one screen pixel (a cell smaller than a pixel cannot move a
    /// silhouette by less than a pixel).
    double worstDisplacementCells = 0.0;
    std::uint32_t worstDisplacementEntity = 0;
    std::size_t overOneCell = 0; ///< entities displaced by more than one virtual pixel
    std::size_t missing = 0;     ///< drawn in exactly one of the two images
};

struct FrameErrorReport {
    EntityErrorSummary all; ///< every entity drawn in either image
    EntityErrorSummary far; ///< of those, the ones the far tier drew (alone or in a cross-fade)
    /// The far tier's own error: each far-drawn entity drawn alone by both tiers
    /// (isolatedFarErrors), so nothing in front of it changes its footprint. Filled in by the
    /// caller (it re-draws).
    EntityErrorSummary farIsolated;
    double rmse = 0.0,
           psnr = 0.0;             ///< colour, core/color_compare.hpp (psnr +inf for equal images)
    std::size_t changedPixels = 0; ///< colour differs
    std::size_t differingPixels = 0; ///< colour, depth or entity id differs
};

/// Mean and worst of `errors`; `sprites` (indexed by entity id) give each entity's cell size.
EntityErrorSummary summarizeEntities(const std::vector<EntityError>& errors,
                                     std::span<const SpriteSetup> sprites);

/// The far tier's own error per entity, free of occlusion: every entity `plan` has the far tier
/// draw (alone or in a cross-fade) is drawn alone, whole, by the near tier's CPU reference (the
/// Vulkan image by contract) and by the far tier with the view the plan chose, and the two are
/// compared. Entities whose screen rectangles do not overlap share a pass, so a pass costs one
/// image per tier. `cache` should be the one that drew the frame (its snapshots are warm).
std::vector<EntityError> isolatedFarErrors(const Scene& scene, const CameraFrame& camera,
                                           std::span<const SpriteSetup> sprites,
                                           std::span<const EntityPlan> plan, SnapshotCache& cache);

/// `truth` is the all-near image of the frame `sprites` describe; `plan` the plan `test` was
/// drawn with (empty: every entity counts as near). Sprites are indexed by entity id.
FrameErrorReport measureFrameError(const Image& truth, const Image& test,
                                   std::span<const SpriteSetup> sprites,
                                   std::span<const EntityPlan> plan);

} // namespace voxtier
