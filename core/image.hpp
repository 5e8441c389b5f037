#pragma once
// The frame every tier writes: RGBA8 colour, reversed-Z depth of the winning sprite (0 where
// nothing was drawn) and the entity id buffer (kernel::VT_NO_ENTITY where nothing was drawn).
#include "core/voxel_model.hpp"

#include <cstdint>
#include <memory>
#include <utility>
#include <vector>

namespace voxtier {

/// std::allocator, except that a vector's new elements are left uninitialised (default-init)
/// instead of zeroed: an image's planes are filled by Image::clear, on every core, so zeroing
/// them first would write the frame's 12 bytes a pixel twice, once on one core.
template <class T> struct UninitialisedAllocator : std::allocator<T> {
    template <class U> struct rebind { using other = UninitialisedAllocator<U>; };
    UninitialisedAllocator() = default;
    template <class U> UninitialisedAllocator(const UninitialisedAllocator<U>&) noexcept {}
    template <class U> void construct(U* p) noexcept { ::new (static_cast<void*>(p)) U; }
    template <class U, class... A> void construct(U* p, A&&... a) {
        ::new (static_cast<void*>(p)) U(std::forward<A>(a)...);
    }
};
/// One plane of an image.
template <class T> using Plane = std::vector<T, UninitialisedAllocator<T>>;

struct Image {
    int width = 0, height = 0;
    Plane<Rgba8> color;
    Plane<float> depth;
    Plane<std::uint32_t> id;

    Image() = default;
    Image(int w, int h, Rgba8 background);
    std::size_t index(int x, int y) const {
        return std::size_t(y) * std::size_t(width) + std::size_t(x);
    }
    std::size_t pixelCount() const { return std::size_t(width) * std::size_t(height); }
    /// Resets every pixel to the background: colour, depth 0, no entity (TBB-parallel: the three
    /// planes of a 960x540 frame are 6 MB).
    void clear(Rgba8 background);
    /// Writes one sprite pixel when it wins the shared depth/id rule (core/sprite.hpp). Inline:
    /// the CPU tiers call it per pixel.
    /// Whether writeIfNearer(i, *, d, entity) would write: the min-z rule (reversed-Z, larger is
    /// nearer) with the deterministic id rule at equal depths.
    bool wouldWrite(std::size_t i, float d, std::uint32_t entity) const {
        return d > depth[i] || (d == depth[i] && entity < id[i]);
    }
    void writeIfNearer(std::size_t i, Rgba8 c, float d, std::uint32_t entity) {
        if (wouldWrite(i, d, entity)) {
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
