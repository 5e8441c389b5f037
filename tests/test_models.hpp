#pragma once
// Models built in code for the tests: a solid box, and a bar marked so that a flipped axis shows.
#include "core/voxel_model.hpp"

#include <glm/glm.hpp>

#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

namespace voxtier::test {

/// A box of `dims` voxels, all of palette index `index` (colour 1 is orange).
inline std::shared_ptr<VoxelModel> solidBox(glm::ivec3 dims, std::uint8_t index = 1) {
    VoxelGrid g(dims);
    for (auto& v : g.data()) v = index;
    Palette p;
    for (int i = 1; i < 256; ++i)
        p.colors[std::size_t(i)] =
            packRgba(unsigned(i * 37 % 256), unsigned(i * 91 % 256), unsigned(i * 53 % 256));
    p.colors[1] = packRgba(200, 120, 40);
    return std::make_shared<VoxelModel>("box", p, std::vector<VoxelGrid>{g});
}

/// A bar along voxel +X (index 1) with a marker voxel (index 2) at the +X end on the +Y side:
/// asymmetric under every mirror, so a flipped axis anywhere shows.
inline std::shared_ptr<VoxelModel> markedBar() {
    auto m = solidBox({6, 2, 1}, 1);
    VoxelGrid g = m->frame(0);
    g.set({5, 1, 0}, 2);
    Palette p = m->palette();
    p.colors[2] = packRgba(20, 220, 60);
    return std::make_shared<VoxelModel>("bar", p, std::vector<VoxelGrid>{g});
}

} // namespace voxtier::test
