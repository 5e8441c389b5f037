#include "impostor_cache/surface_voxels.hpp"

namespace voxtier {

namespace {
constexpr glm::ivec3 kNeighbour[6] = {{-1, 0, 0}, {1, 0, 0}, {0, -1, 0}, {0, 1, 0}, {0, 0, -1}, {0, 0, 1}};
}

std::vector<std::uint32_t> surfaceVoxels(const VoxelGrid& grid, bool surfaceOnly) {
    std::vector<std::uint32_t> out;
    const glm::ivec3 n = grid.dims();
    for (int z = 0; z < n.z; ++z)
        for (int y = 0; y < n.y; ++y)
            for (int x = 0; x < n.x; ++x) {
                const glm::ivec3 p{x, y, z};
                if (grid.at(p) == 0) continue;
                bool exposed = !surfaceOnly;
                for (int k = 0; k < 6 && !exposed; ++k) exposed = grid.atOrEmpty(p + kNeighbour[k]) == 0;
                if (exposed) out.push_back(packVoxel(p));
            }
    return out;
}

std::vector<VoxelFace> exposedFaces(const VoxelGrid& grid, bool surfaceOnly) {
    std::vector<VoxelFace> out;
    const glm::ivec3 n = grid.dims();
    for (int z = 0; z < n.z; ++z)
        for (int y = 0; y < n.y; ++y)
            for (int x = 0; x < n.x; ++x) {
                const glm::ivec3 p{x, y, z};
                if (grid.at(p) == 0) continue;
                // kNeighbour[k] is the neighbour across face code k (code 2a: the - side).
                for (int k = 0; k < 6; ++k)
                    if (!surfaceOnly || grid.atOrEmpty(p + kNeighbour[k]) == 0)
                        out.push_back({packVoxel(p), std::uint8_t(k)});
            }
    return out;
}

} // namespace voxtier
