#pragma once
// How far an approximate frame is from the ground truth (CONTRACT.md §8): per-entity footprint
// mismatch, maximum silhouette displacement, and whole-image RMSE / PSNR. The ground truth is
// the all-near render of the same frame.
#include "core/image.hpp"

#include <glm/glm.hpp>

#include <cstdint>
#include <optional>
#include <vector>

namespace voxtier {

struct EntityError {
    std::uint32_t entity = 0;
    std::size_t footprintTruth = 0; ///< pixels the entity owns in the truth
    std::size_t footprintTest = 0;  ///< pixels it owns in the test image
    std::size_t unionPixels = 0;    ///< owned in either
    std::size_t mismatched =
        0; ///< of the union: owned by only one, or owned by both with different colour
    std::size_t coverageMismatched =
        0; ///< of the union: owned by only one (silhouette, colour ignored)
    /// Largest distance (pixels) from a pixel owned in one image but not the other to the
    /// nearest pixel owned in the other: how far the silhouette moved. 0 when the footprints
    /// agree; +inf when the entity is missing from exactly one image.
    double silhouetteDisplacementPx = 0.0;
    double mismatchFraction() const {
        return unionPixels ? double(mismatched) / double(unionPixels) : 0.0;
    }
    double coverageMismatchFraction() const {
        return unionPixels ? double(coverageMismatched) / double(unionPixels) : 0.0;
    }
};

/// Error of one entity between two images of the same frame.
EntityError entityError(const Image& truth, const Image& test, std::uint32_t entity);

/// Errors of many entities in one pass over the images (entities absent from both are skipped).
/// `rect` (x0, y0, x1, y1, half-open) limits the pass when the footprints are known to lie in it.
std::vector<EntityError> entityErrors(const Image& truth, const Image& test,
                                      const std::vector<std::uint32_t>& entities,
                                      std::optional<glm::ivec4> rect = std::nullopt);

struct FrameError {
    std::size_t entities = 0;
    double meanMismatch = 0.0, worstMismatch = 0.0;
    double meanDisplacementPx = 0.0, worstDisplacementPx = 0.0;
    std::uint32_t worstEntity = 0;
    double rmse = 0.0, psnr = 0.0; ///< colour (core/color_compare.hpp)
    std::size_t changedPixels = 0; ///< pixels whose colour differs
};
FrameError summarize(const std::vector<EntityError>& perEntity, const Image& truth,
                     const Image& test);

/// Exact squared Euclidean distance (pixels) from every cell of a w x h mask to the nearest
/// set cell (Felzenszwalb & Huttenlocher, "Distance Transforms of Sampled Functions", 2012).
/// Cells are +inf when the mask is empty.
std::vector<double> squaredDistanceTransform(const std::vector<std::uint8_t>& mask, int w, int h);

} // namespace voxtier
