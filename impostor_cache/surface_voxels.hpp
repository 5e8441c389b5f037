#pragma once
// The voxels a primary ray can hit first (CONTRACT.md §4, HARD_CASES 19): a solid voxel with at
// least one empty or out-of-bounds 6-neighbour. A ray's traversal is 6-connected and starts on
// the model box, so the first solid voxel it visits is either on the box boundary or entered
// from an empty 6-neighbour: interior voxels are never the first hit, and the face it is
// entered through is an exposed face.
//
// The baker only needs a lower bound of where a ray can meet such a voxel (snapshot_baker.cpp),
// so neighbouring primitives may be merged: a run of surface voxels is one box, a rectangle of
// coplanar exposed faces is one quad. Fewer primitives, a shallower BVH, the same bound.
#include "core/voxel_model.hpp"

#include <glm/glm.hpp>

#include <cstdint>
#include <optional>
#include <vector>

namespace voxtier {

/// Packs a voxel coordinate (each 0..1023) into 30 bits.
inline std::uint32_t packVoxel(glm::ivec3 p) {
    return std::uint32_t(p.x) | std::uint32_t(p.y) << 10 | std::uint32_t(p.z) << 20;
}
inline glm::ivec3 unpackVoxel(std::uint32_t v) {
    return {int(v & 1023u), int((v >> 10) & 1023u), int(v >> 20)};
}

/// Is p a surface voxel (solid, with an empty or out-of-bounds 6-neighbour)?
bool isSurfaceVoxel(const VoxelGrid& grid, glm::ivec3 p);

/// A box of voxels [min, max) (half-open, integer).
struct VoxelRun {
    glm::u16vec3 min, max;
};
/// Surface voxels (every solid voxel with `surfaceOnly == false`) as boxes: single voxels, or
/// with `merge`, maximal runs of consecutive such voxels along x. Memory order. With a `region`
/// (clipped to the grid) only the voxels inside it, runs cut at its faces: a brick of a bricked
/// scene (voxel_scene.hpp). Surface status still looks at neighbours outside the region.
std::vector<VoxelRun> surfaceBoxes(const VoxelGrid& grid, bool surfaceOnly = true,
                                   bool merge = true, std::optional<Box3i> region = std::nullopt);

/// A rectangle of exposed faces in one plane: face code (kernel codes: 2*axis, +1 for the face
/// on the + side), the plane coordinate along the axis, and the covered range [lo, hi) of the
/// two other axes, in the order (axis+1)%3, (axis+2)%3.
struct FaceRect {
    std::uint8_t face;
    std::uint16_t plane;
    glm::u16vec2 lo, hi;
};
/// Faces of solid voxels whose neighbour across the face is empty or out of bounds (all six
/// faces of every solid voxel with `surfaceOnly == false`); with `merge`, greedily merged into
/// rectangles per plane, else one rectangle per face. With a `region`, only the faces of voxels
/// inside it, rectangles cut at its faces.
std::vector<FaceRect> exposedFaces(const VoxelGrid& grid, bool surfaceOnly = true,
                                   bool merge = true, std::optional<Box3i> region = std::nullopt);

} // namespace voxtier
