#include "volumetric/atlas_packer.hpp"

#include <stdexcept>
#include <string>

namespace voxtier {

AtlasPacker::AtlasPacker(int width, int height, int maxDepth)
    : width_(width), height_(height), maxDepth_(maxDepth) {}

glm::ivec3 AtlasPacker::allocate(glm::ivec3 size) {
    if (size.x < 1 || size.y < 1 || size.z < 1 || size.x > width_ || size.y > height_ ||
        size.z > maxDepth_)
        throw std::length_error("voxel block " + std::to_string(size.x) + "x" +
                                std::to_string(size.y) + "x" + std::to_string(size.z) +
                                " does not fit the atlas");
    placed_ += 1LL * size.x * size.y * size.z;
    // First fit: an existing shelf, else a new shelf in an existing slab, else a new slab.
    for (Slab& slab : slabs_) {
        if (size.z > slab.depth) continue;
        for (Shelf& shelf : slab.shelves)
            if (size.y <= shelf.height && shelf.x + size.x <= width_) {
                const glm::ivec3 at{shelf.x, shelf.y, slab.z};
                shelf.x += size.x;
                return at;
            }
        if (slab.nextY + size.y <= height_) {
            slab.shelves.push_back({slab.nextY, size.y, size.x});
            const glm::ivec3 at{0, slab.nextY, slab.z};
            slab.nextY += size.y;
            return at;
        }
    }
    if (top_ + size.z > maxDepth_) {
        placed_ -= 1LL * size.x * size.y * size.z;
        throw std::length_error("voxel atlas full (" + std::to_string(width_) + "x" +
                                std::to_string(height_) + "x" + std::to_string(maxDepth_) + ")");
    }
    Slab slab{top_, size.z, size.y, {{0, size.y, size.x}}};
    top_ += size.z;
    slabs_.push_back(slab);
    return {0, 0, slab.z};
}

} // namespace voxtier
