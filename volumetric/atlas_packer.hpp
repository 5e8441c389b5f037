#pragma once
// Placement of voxel blocks (one per model frame) in the near tier's 3D atlas. Deliberately
// simple: the atlas has a fixed width and height and grows in depth; it is cut along z into
// slabs (as deep as the first block placed in them), each slab into shelves along y, each
// shelf filled along x. Blocks are never moved or freed, so an atlas offset stays valid for
// the life of the atlas. Pure bookkeeping, no Vulkan: the residency copies the voxels.
#include <glm/glm.hpp>

#include <vector>

namespace voxtier {

class AtlasPacker {
  public:
    /// `width` x `height` per slice (each at least the largest block side), at most `maxDepth`
    /// slices.
    AtlasPacker(int width, int height, int maxDepth);

    /// Origin of a new `size` block. Throws std::length_error when the atlas depth limit is
    /// reached.
    glm::ivec3 allocate(glm::ivec3 size);
    /// Slices in use: the atlas image must be at least this deep.
    int usedDepth() const { return top_; }
    int width() const { return width_; }
    int height() const { return height_; }
    int maxDepth() const { return maxDepth_; }
    /// Voxels covered by placed blocks (for a packing-efficiency figure).
    long long placedVolume() const { return placed_; }

  private:
    struct Shelf {
        int y, height, x;
    };
    struct Slab {
        int z, depth, nextY;
        std::vector<Shelf> shelves;
    };
    int width_, height_, maxDepth_;
    int top_ = 0;
    long long placed_ = 0;
    std::vector<Slab> slabs_;
};

} // namespace voxtier
