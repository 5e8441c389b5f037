#pragma once
// The frame every tier writes: RGBA8 colour, reversed-Z depth of the winning sprite (0 where
// nothing was drawn) and the entity id buffer (kernel::VT_NO_ENTITY where nothing was drawn).
#include "core/voxel_model.hpp"

#include <cstdint>
#include <vector>

namespace voxtier {

struct Image {
    int width = 0, height = 0;
    std::vector<Rgba8> color;
    std::vector<float> depth;
    std::vector<std::uint32_t> id;

    Image() = default;
    Image(int w, int h, Rgba8 background);
    std::size_t index(int x, int y) const {
        return std::size_t(y) * std::size_t(width) + std::size_t(x);
    }
    std::size_t pixelCount() const { return std::size_t(width) * std::size_t(height); }
    /// Resets every pixel to the background: colour, depth 0, no entity.
    void clear(Rgba8 background);
    /// Writes one sprite pixel when it wins the shared depth/id rule (core/sprite.hpp). Inline:
    /// the CPU tiers call it per pixel.
    void writeIfNearer(std::size_t i, Rgba8 c, float d, std::uint32_t entity) {
        if (d > depth[i] || (d == depth[i] && entity < id[i])) {
            color[i] = c;
            depth[i] = d;
            id[i] = entity;
        }
    }
    /// Number of pixels an entity owns in the id buffer.
    std::size_t countEntity(std::uint32_t entity) const;
};

/// Pixel-by-pixel comparison of two images of the same size.
struct ImageDiff {
    std::size_t colorDiffs = 0, depthDiffs = 0, idDiffs = 0;
    std::size_t pixelDiffs = 0;         ///< pixels differing in any of colour, depth, id
    std::size_t firstX = 0, firstY = 0; ///< first differing pixel (any channel)
    bool identical() const { return colorDiffs == 0 && depthDiffs == 0 && idDiffs == 0; }
};
ImageDiff diffImages(const Image& a, const Image& b);

} // namespace voxtier
