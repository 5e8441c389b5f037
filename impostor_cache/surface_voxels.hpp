#pragma once
// The voxels a primary ray can hit first (DESIGN.md §4, HARD_CASES 19): a solid voxel with at
// least one empty or out-of-bounds 6-neighbour. A ray's traversal is 6-connected and starts on
// the model box, so the first solid voxel it visits is either on the box boundary or entered
// from an empty 6-neighbour: interior voxels are never the first hit.
#include "core/voxel_model.hpp"

#include <glm/glm.hpp>

#include <cstdint>
#include <vector>

namespace voxtier {

/// Packs a voxel coordinate (each 0..1023) into 30 bits.
inline std::uint32_t packVoxel(glm::ivec3 p) { return std::uint32_t(p.x) | std::uint32_t(p.y) << 10 | std::uint32_t(p.z) << 20; }
inline glm::ivec3 unpackVoxel(std::uint32_t v) { return {int(v & 1023u), int((v >> 10) & 1023u), int(v >> 20)}; }

/// Surface voxels in memory order (x fastest). With `surfaceOnly == false`, every solid voxel.
std::vector<std::uint32_t> surfaceVoxels(const VoxelGrid& grid, bool surfaceOnly = true);

/// One exposed voxel face: the voxel and the face code (kernel codes: 2*axis, +1 for the
/// face on the + side, i.e. the face a ray moving towards -axis enters through).
struct VoxelFace {
    std::uint32_t voxel;
    std::uint8_t face;
};
/// Faces of solid voxels whose neighbour across the face is empty or out of bounds. With
/// `surfaceOnly == false`, all six faces of every solid voxel.
std::vector<VoxelFace> exposedFaces(const VoxelGrid& grid, bool surfaceOnly = true);

} // namespace voxtier
