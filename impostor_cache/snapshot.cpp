#include "impostor_cache/snapshot.hpp"

#include <algorithm>
#include <cmath>

namespace voxtier {

namespace {

/// core/sprite.cpp's rounding of per-sprite kernel inputs: float, subnormals flushed to 0.
/// Repeated here (core keeps its copy private) because the snapshot rays must be the very
/// floats a near sprite with the same lattice gets.
float toKernelFloat(double v) {
    const float f = static_cast<float>(v);
    return std::abs(f) < 1.17549435e-38f ? 0.0f : f;
}
glm::vec3 toKernel(glm::dvec3 v) {
    return {toKernelFloat(v.x), toKernelFloat(v.y), toKernelFloat(v.z)};
}

} // namespace

SpriteLattice snapshotLattice(glm::dvec3 w, glm::ivec3 dims, double sigma, int snapshotScale) {
    w = glm::normalize(w);
    const glm::dvec3 upHint = std::abs(w.z) > 0.99 ? glm::dvec3(1, 0, 0) : glm::dvec3(0, 0, 1);
    SpriteLattice L = makeSpriteLattice(-w, upHint, glm::dvec3(1, 0, 0), dims, sigma);
    const int grow = snapshotScale - 1;
    L.cellRange += glm::ivec4(-grow, grow, -grow, grow);
    return L;
}

kernel::SpriteGpu snapshotRayFrame(const SpriteLattice& L) {
    // Same expressions as setupSprite (core/sprite.cpp) for the ray fields.
    kernel::SpriteGpu g{};
    g.rayBase = toKernel(L.centre + L.gU * L.right + L.gV * L.up - L.dir * (2.0 * L.maxDim));
    g.cellRight = toKernel(L.right / L.sigma);
    g.cellUp = toKernel(L.up / L.sigma);
    g.dir = toKernel(L.dir);
    g.invDir = toKernel(glm::dvec3(L.dir.x != 0.0 ? 1.0 / L.dir.x : 0.0,
                                   L.dir.y != 0.0 ? 1.0 / L.dir.y : 0.0,
                                   L.dir.z != 0.0 ? 1.0 / L.dir.z : 0.0));
    g.cellRange = L.cellRange;
    g.dims = glm::uvec4(glm::uvec3(L.dims), 0u);
    return g;
}

std::size_t Snapshot::bytes() const {
    return sizeof(Snapshot) + cells.capacity() * sizeof(SnapshotCell) +
           depth.capacity() * sizeof(float);
}

std::size_t Snapshot::solidCount() const {
    std::size_t n = 0;
    for (const SnapshotCell& c : cells) n += snapshot_code::isSolid(c.code);
    return n;
}

void applyCardinalOutline(Snapshot& s) {
    refreshCardinalOutline(s, {0, s.width() - 1, 0, s.height() - 1});
}

void refreshCardinalOutline(Snapshot& s, glm::ivec4 cells) {
    const int w = s.width(), h = s.height(), k = s.snapshotScale;
    auto solid = [&](int x, int y) {
        return x >= 0 && y >= 0 && x < w && y < h &&
               snapshot_code::isSolid(
                   s.cells[std::size_t(y) * std::size_t(w) + std::size_t(x)].code);
    };
    // Only non-solid cells are written, and only solidity is read: writing in place never feeds
    // a new outline cell into the dilation.
    for (int y = std::max(0, cells.z); y <= std::min(h - 1, cells.w); ++y)
        for (int x = std::max(0, cells.x); x <= std::min(w - 1, cells.y); ++x) {
            SnapshotCell& c = s.cells[std::size_t(y) * std::size_t(w) + std::size_t(x)];
            if (snapshot_code::isSolid(c.code)) continue;
            const bool outline =
                solid(x - k, y) || solid(x + k, y) || solid(x, y - k) || solid(x, y + k);
            c = {0, outline ? snapshot_code::kOutline : snapshot_code::kEmpty};
        }
}

} // namespace voxtier
