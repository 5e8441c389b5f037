#include "impostor_cache/surface_voxels.hpp"

namespace voxtier {

namespace {
/// kNeighbour[k] is the neighbour across face code k (code 2a: the - side of axis a).
constexpr glm::ivec3 kNeighbour[6] = {{-1, 0, 0}, {1, 0, 0},  {0, -1, 0},
                                      {0, 1, 0},  {0, 0, -1}, {0, 0, 1}};

Box3i clippedRegion(const VoxelGrid& grid, const std::optional<Box3i>& region) {
    const Box3i all{{0, 0, 0}, grid.dims()};
    return region ? region->intersected(all) : all;
}
} // namespace

bool isSurfaceVoxel(const VoxelGrid& grid, glm::ivec3 p) {
    if (grid.at(p) == 0) return false;
    for (int k = 0; k < 6; ++k)
        if (grid.atOrEmpty(p + kNeighbour[k]) == 0) return true;
    return false;
}

std::vector<VoxelRun> surfaceBoxes(const VoxelGrid& grid, bool surfaceOnly, bool merge,
                                   std::optional<Box3i> region) {
    std::vector<VoxelRun> out;
    const Box3i r = clippedRegion(grid, region);
    if (r.empty()) return out;
    for (int z = r.min.z; z < r.max.z; ++z)
        for (int y = r.min.y; y < r.max.y; ++y)
            for (int x = r.min.x; x < r.max.x;) {
                auto wanted = [&](int xx) {
                    const glm::ivec3 p{xx, y, z};
                    return surfaceOnly ? isSurfaceVoxel(grid, p) : grid.at(p) != 0;
                };
                if (!wanted(x)) {
                    ++x;
                    continue;
                }
                int x1 = x + 1;
                if (merge)
                    while (x1 < r.max.x && wanted(x1)) ++x1;
                out.push_back({glm::u16vec3(x, y, z), glm::u16vec3(x1, y + 1, z + 1)});
                x = x1;
            }
    return out;
}

std::vector<FaceRect> exposedFaces(const VoxelGrid& grid, bool surfaceOnly, bool merge,
                                   std::optional<Box3i> region) {
    std::vector<FaceRect> out;
    const Box3i r = clippedRegion(grid, region);
    if (r.empty()) return out;
    const glm::ivec3 n = r.max - r.min;
    std::vector<std::uint8_t> mask;
    for (int face = 0; face < 6; ++face) {
        const int a = face / 2, b = (a + 1) % 3, c = (a + 2) % 3;
        const int nb = n[b], nc = n[c];
        mask.assign(std::size_t(nb) * std::size_t(nc), 0);
        for (int s = r.min[a]; s < r.max[a]; ++s) {
            // The faces with code `face` of the voxels in slice s (plane s, or s+1 on the + side).
            // vb, vc are relative to the region.
            bool any = false;
            for (int vc = 0; vc < nc; ++vc)
                for (int vb = 0; vb < nb; ++vb) {
                    glm::ivec3 p;
                    p[a] = s, p[b] = r.min[b] + vb, p[c] = r.min[c] + vc;
                    const bool exposed =
                        grid.at(p) != 0 &&
                        (!surfaceOnly || grid.atOrEmpty(p + kNeighbour[face]) == 0);
                    mask[std::size_t(vc) * std::size_t(nb) + std::size_t(vb)] = exposed;
                    any |= exposed;
                }
            if (!any) continue;
            const auto plane = std::uint16_t(s + face % 2);
            // Greedy rectangles: grow along b, then along c while the whole row span is set.
            for (int vc = 0; vc < nc; ++vc)
                for (int vb = 0; vb < nb; ++vb) {
                    if (!mask[std::size_t(vc) * std::size_t(nb) + std::size_t(vb)]) continue;
                    int b1 = vb + 1, c1 = vc + 1;
                    if (merge) {
                        while (b1 < nb && mask[std::size_t(vc) * std::size_t(nb) + std::size_t(b1)])
                            ++b1;
                        for (bool grow = true; grow && c1 < nc;) {
                            for (int k = vb; k < b1 && grow; ++k)
                                grow =
                                    mask[std::size_t(c1) * std::size_t(nb) + std::size_t(k)] != 0;
                            if (grow) ++c1;
                        }
                    }
                    for (int cc = vc; cc < c1; ++cc)
                        for (int k = vb; k < b1; ++k)
                            mask[std::size_t(cc) * std::size_t(nb) + std::size_t(k)] = 0;
                    out.push_back({std::uint8_t(face), plane,
                                   glm::u16vec2(r.min[b] + vb, r.min[c] + vc),
                                   glm::u16vec2(r.min[b] + b1, r.min[c] + c1)});
                }
        }
    }
    return out;
}

} // namespace voxtier
