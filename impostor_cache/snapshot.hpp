#pragma once
// One baked view of one model frame (CONTRACT.md §4): the near tier's cell image for d = -w on the
// §3.5 lattice, stored as a relightable payload of two bytes per cell (palette index + code).
// Colour and light are applied at blit time, so a light change never needs a re-bake.
#include "core/scene.hpp"
#include "core/sprite.hpp"
#include "core/view_set.hpp"

#include <glm/glm.hpp>

#include <cstddef>
#include <cstdint>
#include <vector>

namespace voxtier {

/// Per-cell code: what the near kernel's vtShadeCell returns for that cell, folded into a byte.
namespace snapshot_code {
inline constexpr std::uint8_t kEmpty = 0;
/// A voxel was hit through entered face f (0..5, kernel face codes): code kSolid0 + f.
inline constexpr std::uint8_t kSolid0 = 1;
inline constexpr std::uint8_t kOutline = 7; ///< no hit, a cardinal neighbour cell hit
inline bool isSolid(std::uint8_t code) {
    return code >= kSolid0 && code < kSolid0 + 6;
}
inline unsigned face(std::uint8_t code) {
    return unsigned(code - kSolid0);
}
} // namespace snapshot_code

struct SnapshotCell {
    std::uint8_t index = 0; ///< palette index of the hit voxel (0 unless solid)
    std::uint8_t code = snapshot_code::kEmpty;
    bool operator==(const SnapshotCell&) const = default;
};
static_assert(sizeof(SnapshotCell) == 2);

/// The snapshot lattice of view w (CONTRACT.md §4): exactly makeSpriteLattice with dir = -w,
/// up from the model's +Z, or +X when |w.Z| > 0.99 (a ±Z view has no usable +Z projection).
/// Its cell range is grown by snapshotScale - 1 cells on every side: the outline ring of a
/// snapshot of that scale (Snapshot::snapshotScale) is that much wider.
SpriteLattice snapshotLattice(glm::dvec3 w, glm::ivec3 dims, double sigma, int snapshotScale = 1);

/// The kernel inputs that describe the snapshot's rays (rayBase, cellRight, cellUp, dir, invDir,
/// dims, cellRange), rounded to float exactly as core/sprite.cpp rounds a near sprite's, so
/// that the ray of snapshot cell (a, b) is bit-identical to the near kernel's ray for the same
/// lattice cell. Screen-mapping, light and atlas fields are zero.
kernel::SpriteGpu snapshotRayFrame(const SpriteLattice& lattice);

struct Snapshot {
    ViewId view;
    glm::dvec3 w{0.0};     ///< viewDirection(view): unit, towards the viewer (voxel space)
    SpriteLattice lattice; ///< the stored cells are lattice.cellRange (inclusive)
    /// Row-major, j (up) outer, i (right) inner; lattice.width() x lattice.height(). Cells
    /// outside the range are empty by construction of cellRange (it holds the whole footprint
    /// plus the outline ring plus slack).
    std::vector<SnapshotCell> cells;
    /// Optional (BakeOptions::withDepth): distance along d from the sprite plane to the entered
    /// voxel face of solid cells (voxels; + is away from the viewer), for reprojection. Empty
    /// when not baked.
    std::vector<float> depth;
    /// The scene's snapshot_scale k this was baked for (BakeOptions::snapshotScale), which is also
    /// the outline's reach in cells: an empty cell is outline when the cell k steps away along a
    /// lattice axis is solid. A snapshot baked at k times a sprite's sigma reaches k cells, since
    /// the sprite's neighbour cells lie k snapshot cells away: at a canonical view with an odd k
    /// the codes are then the near kernel's outline exactly.
    int snapshotScale = 1;

    int width() const { return lattice.width(); }
    int height() const { return lattice.height(); }
    std::size_t cellIndex(int i, int j) const {
        return std::size_t(j - lattice.cellRange.z) * std::size_t(width()) +
               std::size_t(i - lattice.cellRange.x);
    }
    bool inRange(int i, int j) const {
        return i >= lattice.cellRange.x && i <= lattice.cellRange.y && j >= lattice.cellRange.z &&
               j <= lattice.cellRange.w;
    }
    /// The cell at lattice coordinates (i, j); empty outside the stored range.
    SnapshotCell at(int i, int j) const {
        return inRange(i, j) ? cells[cellIndex(i, j)] : SnapshotCell{};
    }
    /// Bytes held (payload + depth + the object itself): what the cache budget counts.
    std::size_t bytes() const;
    std::size_t solidCount() const;
};

/// Marks every empty cell with a solid cell s.snapshotScale cells away along a lattice axis as
/// outline (CONTRACT.md §4: a cardinal 2D dilation of the coverage mask, which equals the near
/// kernel's neighbour-ray rule because the neighbour rays are the neighbour cells' own primary
/// rays, k snapshot cells away on a snapshot k times finer).
void applyCardinalOutline(Snapshot& s);
/// The same rule for the cells of `cells` only (inclusive range of stored-cell coordinates x0,
/// x1, y0, y1, clipped to the snapshot): every cell there that is not solid becomes outline or
/// empty from the current solid mask. Used after re-tracing part of a snapshot.
void refreshCardinalOutline(Snapshot& s, glm::ivec4 cells);

} // namespace voxtier
