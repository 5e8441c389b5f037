#pragma once
// What the rasteriser covers per near sprite (DESIGN.md §3.10): the corners of its proxy in clip
// space, computed on the host in double, camera-relative. Quad and Hull cover every pixel whose
// kernel outcome can be non-empty, with margin, so the image is exact with either; they differ
// only in how many fragments run the kernel to find out it is empty.
#include "core/camera.hpp"
#include "core/sprite.hpp"

#include <array>
#include <span>

namespace voxtier {

/// What the GPU rasterises per sprite.
enum class NearProxy {
    /// The camera-facing quad of SpriteGpu::quad: the bounding rectangle of the cells that can be
    /// non-empty plus one cell and two pixels.
    Quad,
    /// The proxy box (model bounds + 1/sigma), rasterised in perspective: loses outline pixels at
    /// close range, where eye rays diverge from the sprite's parallel rays. Measured only.
    Box,
    /// Default. The model box projected along the sprite's parallel rays onto the sprite plane (a
    /// hexagon), grown by the kernel's exact reach (outline ring + half a cell = 1.5 cells) and
    /// two pixels, drawn as a fan of at most 10 triangles: exact like the quad, with fewer
    /// fragments (the quad's rectangle corners and extra cells go).
    Hull,
};

/// Most corners a hull has (a box's parallel projection grown by a square: at most 10; the
/// shaders' NEAR_HULL_MAX_VERTICES).
inline constexpr int kMaxHullCorners = 12;

/// The clip-space corners of a sprite's proxy box (model bounds grown by 1/sigma voxel), corner
/// k = (k & 1, k >> 1 & 1, k >> 2).
std::array<glm::dvec4, 8> proxyBoxClipCorners(const CameraFrame& camera, const SpriteSetup& sprite);

/// The clip-space corners of a sprite's hull (NearProxy::Hull), a convex polygon in fan order,
/// into `out`; returns how many (3 to kMaxHullCorners). Allocates nothing: the near tier computes
/// it for every sprite of every frame, in parallel.
int proxyHullClipCorners(const CameraFrame& camera, const SpriteSetup& sprite,
                         std::span<glm::dvec4, kMaxHullCorners> out);

} // namespace voxtier
